"""The Taylor-Flanagan explicit contact: a predictor, then the penetrating dofs stopped.

L. M. Taylor, D. P. Flanagan, *PRONTO 2D: a two-dimensional transient solid dynamics
program*, Sandia report SAND86-0594 (1987), as GetFEM's ``demo_dynamic_contact_1D.py`` writes it
(version 4, explicit Newmark, standard mass): the central-difference predictor

    U* = U^n + dt V^n + dt^2/2 a^n,   V* = V^n + dt/2 a^n     (a^n = M^-1 (L(t_n) - A U^n)),

then, at the constrained dofs P where U* would penetrate (U*_c < bound), a contact force lam
that sets their velocity to zero over the step: V^{n+1/2} = V* + dt M^-1 lam with
V^{n+1/2}_P = 0, U^{n+1} = U^n + dt V^{n+1/2}, and V^{n+1} = V^{n+1/2} + dt/2 a^{n+1} (the
velocity of :mod:`~sdm_dolfinx.schemes.explicit`). In X = U^{n+1} it is the LCP

    (M / dt^2) X = M U* / dt^2 + lam,   X_P >= U^n_P,  lam_P >= 0, complementary (lam = 0 off P),

the velocity-level constraint V^{n+1/2}_P >= 0. Choices taken where the sources leave one open:

* GetFEM's demo imposes the equality V_P = 0, a pulling force when a penetrating dof already
  moves away; we impose V_P >= 0 with lam >= 0, which coincides whenever the dof approaches and
  never glues it;
* P is decided by the predictor only (no second pass): with a diagonal (row-sum) mass the dofs
  are uncoupled, U^{n+1}_P = U^n_P and no constrained dof ever goes below its bound when U^0 does
  not; with the consistent mass the correction of P moves the other dofs too, which may then
  dip below their bound by O(dt^2) until the next step catches them;
* the mass must be invertible (a massless dof has no velocity to stop: refused), and the step
  solver the semi-smooth Newton (its bounds change every step).

dt is refused beyond the CFL bound 2/omega_max of M^-1 A, as central differences'.
"""
import numpy as np

from sdm_dolfinx.schemes.explicit import ExplicitScheme


class TaylorFlanagan(ExplicitScheme):
    name = "taylor-flanagan"
    constrained = "V^{n+1/2} >= 0 where U^{n+1} would penetrate"

    def refuse(self, integ):
        refused = super().refuse(integ)
        if refused is None and integ.vi_solver != "ssn":
            refused = (f"scheme 'taylor-flanagan' changes the step's bounds every step, which only the semi-smooth "
                       f"Newton (vi_solver 'ssn') follows, not {integ.vi_solver!r}")
        return refused

    def solver_bounds(self, integ):
        """A copy of the bounds, set every step: U^n at the dofs that would penetrate, -inf elsewhere."""
        self.bounds = np.array(integ.discretisation.lb, copy=True)
        return self.bounds

    def rhs(self, integ, U, V, L, t):
        d = integ.discretisation
        pred = self.predictor(integ, U, V, t)
        self.P = pred.array_r[d.cdofs] < d.lb
        self.bounds[:] = np.where(self.P, U.array_r[d.cdofs], -np.inf)
        integ.solver.active = integ.solver.active & self.P      # an unbounded dof cannot stay active
        return self.mass_rhs(integ, pred)

    def imposed_gap(self, integ, X):
        """min over P of V^{n+1/2} dt = U^{n+1} - U^n (>= 0: the velocity-level constraint)."""
        d = integ.discretisation
        return float(np.min(X.array_r[d.cdofs][self.P] - self.bounds[self.P], initial=np.inf))

    def update(self, integ, X, U, V, t):
        self.finish(integ, X.array_r.copy(), U, V, t)


SCHEME = TaylorFlanagan()
