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


class RowsStep(FiniteStrainStep):
    """What the variants whose constraints are rows given before every step (gap rows, friction) share: the
    step's rows applied to every linear solver made (:meth:`_solver`, one per tangent), and the error measured
    against the last linear solve's reaction (:meth:`~.FiniteStrainStep._reaction_error`)."""

    def __init__(self, integ, material, newton, linear, options):
        super().__init__(integ, material, newton, linear, options)
        self.rows = None                    # the step's rows: set_rows, before every step
        self.last = None                    # the solver of the last Newton iteration

    def _solver(self, K, spd, factor_matrix, prefix):
        """A new linear solver of the step matrix K (the variant's)."""
        raise NotImplementedError

    def _make(self, K, spd, factor_matrix, prefix):
        solver = self._solver(K, spd, factor_matrix, prefix)
        if self.rows is not None:
            solver.set_rows(*self.rows)
        return solver

    def set_rows(self, *rows):
        """The rows of the next step (obstacles: linearised at U^n, their frames; the weighted gap's g), for
        every solver of the step."""
        self.rows = rows
        for s in (self.lcp, self.lcp0):
            if s is not None:
                s.set_rows(*rows)

    def _frames(self):
        """A linear solver with the step's rows (the last iteration's, or any), or None."""
        return self.last or self.lcp or self.lcp0

    def imposed_gap(self, x):
        """min over this rank's rows of the imposed gap, by a solver with the step's rows (collective for
        matrix rows)."""
        solver = self._frames()
        return solver.imposed_gap(x) if solver is not None else float("inf")

    def _error(self, res, scale):
        """max |r(X) - b - R^T lam| off the Dirichlet dofs over ``scale``, lam the last iteration's (collective)."""
        return self._reaction_error(res, scale)


class GapFiniteStrainStep(RowsStep):
    """The step solver of a hyperelastic run of ``integ`` whose Discretisation has gap rows."""

    def __init__(self, integ, material, newton, linear, options):
        super().__init__(integ, material, newton, linear, options)
        self.active = None

    def _solver(self, K, spd, factor_matrix, prefix):
        return gap_solver(self.discretisation, K, "ssn", spd, self.options, factor_matrix)[0]

    def _solve_linear(self, lcp, rhs, X):
        if self.active is not None:
            lcp.active = self.active.copy()
        its = lcp.solve(rhs, X)["its"]
        self.active, self.last = lcp.active.copy(), lcp
        self._reaction(lcp, rhs, X)
        return its

    def _converged(self, res):
        """The rows' multipliers of the last iteration, and how many are active."""
        self.lam = np.array(self.last.lam) if self.last is not None else np.zeros(0)
        n = 0 if self.active is None else int(np.count_nonzero(self.active))
        return {"n_active": self.discretisation.comm.allreduce(n, op=MPI.SUM)}
