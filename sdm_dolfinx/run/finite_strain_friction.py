"""The step of a hyperelastic run with friction (Tresca or Coulomb) at the constrained vertices.

The step is the frictionless one of :mod:`.finite_strain_step` with the frictional conditions of
:mod:`sdm_dolfinx.contact.friction` at the contact vertices: with r(X) the step's residual
c_M M X + c_A F_int(X; U^n) - b, r(X) = lam at the contact dofs (lam_N normal, lam_T tangential),
the Signorini conditions on lam_N and the friction law on lam_T against the slip d = X_t - U^n_t.
Each Newton iteration at X_k is the linear step's frictional problem with the step matrix
K_k = c_M M + c_A T(X_k):  K_k X = K_k X_k - r(X_k) + lam,  solved by the frictional semi-smooth
Newton (:class:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton`, 3-D
:class:`~sdm_dolfinx.solvers.friction_cone.FrictionalNewtonCone`), one per tangent, started from the
previous iteration's contact, stick and slip sets. The step ends when r(X) differs from the last
iteration's multipliers by less than the tolerance (:data:`~.finite_strain_step.RTOL` of the step's
scale) at every dof: the linearisation's error, quadratic in the step.

Why the energy balance of the linear runs carries over: the energy-momentum stress makes the step's
internal work exactly the strain energy's change (:mod:`sdm_dolfinx.materials.algorithmic`), so
E^{n+1} - E^n = lam . (U^{n+1} - U^n) as in the linear midpoint scheme, and its tangential part is
2 sum lam_T . d = -2 sum g |d| <= 0 (a sticking vertex, d = 0, does no work). The obstacle is the
plane of the constrained component (x_c >= lb): its normal and tangents are the coordinate axes in
the current configuration too, so the contact conditions are exact at any displacement.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.run.finite_strain_step import FiniteStrainStep


class FrictionalFiniteStrainStep(FiniteStrainStep):
    """The step solver of a hyperelastic run of ``integ`` with friction; ``factory(K, spd, factor_matrix,
    prefix)`` makes the frictional solver of one step matrix (:func:`sdm_dolfinx.contact.friction.solver_factory`)."""

    def __init__(self, integ, material, newton, linear, options, factory):
        super().__init__(integ, material, newton, linear, options)
        self.factory = factory
        self.ndofs, self.tdofs = np.asarray(self.discretisation.cdofs), np.asarray(integ.tdofs)
        m = len(self.ndofs)
        self.lam_t = np.zeros(self.tdofs.shape)
        self.stick, self.slip = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
        # the last Newton iteration's sets and multipliers (the next iteration, and the next step, start there)
        self._sets, self._lin = None, (np.zeros(m), np.zeros(self.tdofs.shape))
        self.xref = None
        self.counts = {}

    def _make(self, K, spd, factor_matrix, prefix):
        return self.factory(K, spd, factor_matrix, prefix)

    def tangential(self, u):
        """The tangential components of the owned array ``u`` at the contact vertices (the order of the
        frictional solvers' ``tdofs``; a copy)."""
        return np.array(np.asarray(u)[self.tdofs], dtype=float)

    def cartesian(self, tangential):
        """The tangential vectors as the frictional solvers give them (the axes are Cartesian here)."""
        return np.asarray(tangential, dtype=float)

    def solve(self, b, X, xref_t):
        """As :meth:`FiniteStrainStep.solve`; ``xref_t``: U^n at the tangential dofs (the slip's reference)."""
        self.xref = np.asarray(xref_t, dtype=float)
        return super().solve(b, X)

    def _solve_linear(self, lcp, rhs, X):
        """One Newton iteration's frictional problem from the last iteration's sets and multipliers."""
        if self._sets is not None:
            lcp._sets = tuple(np.array(v, copy=True) for v in self._sets)
        lcp.lam, lcp.lam_t = (np.array(v, copy=True) for v in self._lin)
        info = lcp.solve(rhs, X, self.xref)
        self._sets, self._lin = lcp._sets, (lcp.lam.copy(), lcp.lam_t.copy())
        self.active, self.stick, self.slip = lcp.active.copy(), lcp.stick.copy(), lcp.slip.copy()
        self.counts = {k: info[k] for k in ("n_stick", "n_slip")}
        return info["its"]

    def _error(self, res, scale):
        """max |r(X) - lam| over ``scale``, lam the last iteration's multipliers at the contact dofs and 0
        elsewhere (collective)."""
        e = np.abs(np.where(self.free, res, 0.0))
        lam_n, lam_t = self._lin
        e[self.ndofs] = np.abs(res[self.ndofs] - lam_n)
        e[self.tdofs] = np.abs(res[self.tdofs] - lam_t)
        return self.discretisation.comm.allreduce(float(np.max(e, initial=0.0)), op=MPI.MAX) / scale

    def _converged(self, res):
        """The reactions of the converged step: r(X) - b at the contact vertices' normal dofs (active) and
        tangential ones (sticking or slipping), 0 elsewhere."""
        info = super()._converged(res)
        rubs = self.stick | self.slip
        self.lam_t = np.where(rubs.reshape((-1,) + (1,) * (self.tdofs.ndim - 1)), res[self.tdofs], 0.0)
        return {**info, **self.counts}
