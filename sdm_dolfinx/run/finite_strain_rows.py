"""The step of a hyperelastic run against gap rows G x >= g: rigid obstacles (curved, tilted, moving)
and the weighted gap (``constrain="weighted"``), frictionless.

The step is the frictionless one of :mod:`.finite_strain_step` with the constraint G X >= g: r(X) = G^T lam,
lam >= 0, complementary. The rows are the linear runs' (:mod:`sdm_dolfinx.method.obstacle_rows`): each
obstacle's are linearised at U^n before every step (the normal and the signed distance at the node's
position X + U^n), the weighted gap's are fixed; the flat foundation's are exact at any displacement.
Each Newton iteration at X_k solves  K_k X = K_k X_k - r(X_k) + G^T lam  with K_k = c_M M + c_A T(X_k) by the
gap rows' semi-smooth Newton (:class:`~sdm_dolfinx.solvers.gap_newton.GapNewton`), one per tangent, started
from the previous active set. Its reaction G^T lam = K_k X - rhs is the residual's next value to first
order: the step ends when r(X) differs from it by less than :data:`~.finite_strain_step.RTOL` of the step's
scale off the Dirichlet dofs.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.method.gap_solver import gap_solver
from sdm_dolfinx.run.finite_strain_step import FiniteStrainStep


class GapFiniteStrainStep(FiniteStrainStep):
    """The step solver of a hyperelastic run of ``integ`` whose Discretisation has gap rows."""

    def __init__(self, integ, material, newton, linear, options):
        super().__init__(integ, material, newton, linear, options)
        self.rows = None                    # (coef, g) of the step: set_rows, before every step
        self.last = None                    # the solver of the last Newton iteration
        self.active = None

    def _make(self, K, spd, factor_matrix, prefix):
        solver = gap_solver(self.discretisation, K, "ssn", spd, self.options, factor_matrix)[0]
        if self.rows is not None:
            solver.set_rows(*self.rows)
        return solver

    def set_rows(self, coef, g):
        """The rows of the next step (obstacles: linearised at U^n; the weighted gap's g)."""
        self.rows = (coef, g)
        for s in (self.lcp, self.lcp0):
            if s is not None:
                s.set_rows(coef, g)

    def imposed_gap(self, x):
        """min over this rank's rows of G x - g, by the last iteration's solver (collective for matrix rows)."""
        return self.last.imposed_gap(x) if self.last is not None else float("inf")

    def _solve_linear(self, lcp, rhs, X):
        if self.active is not None:
            lcp.active = self.active.copy()
        its = lcp.solve(rhs, X)["its"]
        self.active, self.last = lcp.active.copy(), lcp
        self._reaction(lcp, rhs, X)
        return its

    def _error(self, res, scale):
        """max |r(X) - G^T lam| off the Dirichlet dofs over ``scale``, lam the last iteration's (collective)."""
        return self._reaction_error(res, scale)

    def _converged(self, res):
        """The rows' multipliers of the last iteration, and how many are active."""
        self.lam = np.array(self.last.lam) if self.last is not None else np.zeros(0)
        n = 0 if self.active is None else int(np.count_nonzero(self.active))
        return {"n_active": self.discretisation.comm.allreduce(n, op=MPI.SUM)}
