"""The step of a hyperelastic run with friction (Tresca or Coulomb): at the constrained vertices, against
obstacles, with the weighted gap.

The step is the frictionless one of :mod:`.finite_strain_step` with the frictional conditions of
:mod:`sdm_dolfinx.contact.friction` at the contact vertices: with r(X) the step's residual
c_M M X + c_A F_int(X; U^n) - b, r(X) = lam at the contact dofs (lam_N normal, lam_T tangential),
the Signorini conditions on lam_N and the friction law on lam_T against the slip d = X_t - U^n_t.
Each Newton iteration at X_k is the linear step's frictional problem with the step matrix
K_k = c_M M + c_A T(X_k):  K_k X = K_k X_k - r(X_k) + lam,  solved by the frictional semi-smooth
Newton (:class:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton`, 3-D
:class:`~sdm_dolfinx.solvers.friction_cone.FrictionalNewtonCone`), one per tangent, started from the
previous iteration's contact, stick and slip sets. The step ends when r(X) differs from the last
iteration's reaction K_k X - rhs (its multipliers at the contact dofs) by less than the tolerance
(:data:`~.finite_strain_step.RTOL` of the step's scale) at every dof: the linearisation's error, quadratic
in the step. Against obstacles the conditions are in each node's frame (normal, tangents) of the obstacle
at U^n, given before every step, as in the linear runs.

Why the energy balance of the linear runs carries over: the energy-momentum stress makes the step's
internal work exactly the strain energy's change (:mod:`sdm_dolfinx.materials.algorithmic`), so
E^{n+1} - E^n = lam . (U^{n+1} - U^n) as in the linear midpoint scheme, and its tangential part is
2 sum lam_T . d = -2 sum g |d| <= 0 (a sticking vertex, d = 0, does no work). The flat foundation
(x_c >= lb) has the coordinate axes as its normal and tangents in the current configuration too, so its
conditions are exact at any displacement; a curved obstacle's frames are those at U^n, first order in the
step's motion.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.run.finite_strain_rows import RowsStep


class FrictionalFiniteStrainStep(RowsStep):
    """The step solver of a hyperelastic run of ``integ`` with friction; ``factory(K, spd, factor_matrix,
    prefix)`` makes the frictional solver of one step matrix (:func:`sdm_dolfinx.contact.friction.solver_factory`).
    Against obstacles (or with the weighted gap) the contact "dofs" are the nodes' frame components (or the
    rows' values), given before every step by :meth:`~.RowsStep.set_rows`, as in the linear runs."""

    def __init__(self, integ, material, newton, linear, options, factory):
        super().__init__(integ, material, newton, linear, options)
        self.factory = factory
        self.tdofs = np.asarray(integ.tdofs)
        m = len(self.tdofs)
        self.lam, self.lam_t = np.zeros(m), np.zeros(self.tdofs.shape)
        self.stick, self.slip = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
        # the last Newton iteration's sets and multipliers (the next iteration, and the next step, start there)
        self._sets, self._lin = None, (np.zeros(m), np.zeros(self.tdofs.shape))
        self.xref, self.counts = None, {}
        d = self.discretisation
        if d.obstacle_rows is not None or d.weighted_rows is not None:
            # the slip and the fields are read in the frames or rows from the first step (a restart's too): the
            # solver at rest is made now (one factorisation for the run, also the fallback's)
            self._initial()

    def _solver(self, K, spd, factor_matrix, prefix):
        return self.factory(K, spd, factor_matrix, prefix)

    def tangential(self, u):
        """The tangential components of the owned array ``u`` at the contact nodes (the order of ``tdofs``;
        in the step's frames against obstacles; a copy)."""
        solver = self._frames()
        return solver.tangential(u) if solver is not None else np.array(np.asarray(u)[self.tdofs], dtype=float)

    def cartesian(self, tangential):
        """The tangential vectors as Cartesian ones (3-D frames), else themselves."""
        solver = self._frames()
        return solver.cartesian(tangential) if solver is not None else np.asarray(tangential, dtype=float)

    def frame_tangential(self, vectors):
        """The tangential components of Cartesian vectors at the nodes, in the step's frames (obstacles)."""
        return self._frames().frame_tangential(vectors)

    def solve(self, b, X, xref_t):
        """As :meth:`FiniteStrainStep.solve`; ``xref_t``: the slip's reference (U^n's tangential components)."""
        self.xref = np.asarray(xref_t, dtype=float)
        return super().solve(b, X)

    def _solve_linear(self, lcp, rhs, X):
        """One Newton iteration's frictional problem from the last iteration's sets and multipliers."""
        if self._sets is not None:
            lcp._sets = tuple(np.array(v, copy=True) for v in self._sets)
        lcp.lam, lcp.lam_t = (np.array(v, copy=True) for v in self._lin)
        info = lcp.solve(rhs, X, self.xref)
        self._sets, self._lin, self.last = lcp._sets, (lcp.lam.copy(), lcp.lam_t.copy()), lcp
        self.active, self.stick, self.slip = lcp.active.copy(), lcp.stick.copy(), lcp.slip.copy()
        self.counts = {k: info[k] for k in ("n_stick", "n_slip")}
        self._reaction(lcp, rhs, X)
        return info["its"]

    def _converged(self, res):
        """The last iteration's multipliers (normal and tangential, in the frames) and counts."""
        self.lam, self.lam_t = (np.array(v, copy=True) for v in self._lin)
        n = self.discretisation.comm.allreduce(int(np.count_nonzero(self.active)), op=MPI.SUM)
        return {"n_active": n, **self.counts}
