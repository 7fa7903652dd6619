"""The Paoli-Schatzman scheme: central differences with an impact law of restitution e.

L. Paoli, M. Schatzman, *A numerical scheme for impact problems I: the one-dimensional case*
and *II: the multidimensional case*, SIAM J. Numer. Anal. 40 (2002) 702-733 and 734-768 (as in
GetFEM's ``demo_dynamic_contact_1D.py``, version 1, and D. Doyen, A. Ern, S. Piperno, SIAM J.
Sci. Comput. 33 (2011) 223-249): the central-difference step

    M (U^{n+1} - 2 U^n + U^{n-1}) / dt^2 + A U^n = L(t_n) + lam^n

with the constraint on the weighted iterate X = (U^{n+1} + e U^{n-1}) / (1 + e):

    X >= bound,  lam^n >= 0,  lam^n . (X - bound) = 0,

so that a dof hitting the obstacle leaves it with e times its arrival speed (e = 0: it stays,
e = 1: it bounces back). In X each step is the LCP

    ((1 + e) M / dt^2) X = M (2 U^n - (1 - e) U^{n-1}) / dt^2 + L - A U^n + lam.

Choices taken where the literature leaves one open:

* e = ``scheme_options["restitution"]`` in [0, 1], default 0 (the inelastic impact of the
  continuous elastic problem: the energy is carried by the elastic waves, not by the bounce);
* U^{n-1} is not stored: with the velocity V^n = (U^n - U^{n-1})/dt + dt/2 a^n (GetFEM's explicit
  Newmark velocity, a^n = M^-1 (L - A U^n)), U^{n-1} = U^n - dt V^n + dt^2/2 a^n exactly; at the
  first step this defines U^{-1} from (U^0, V^0) (the central-difference start, so that e = 0 is
  the central-difference step with the constraint on U^{n+1} exactly);
* the mass must be invertible (``"standard"`` or ``"row-sum"``): at a massless dof the impact
  law has no velocity to act on (a singular mass is refused; central-difference handles it).

dt is refused beyond the CFL bound 2/omega_max of M^-1 A, as central differences'.
"""
from sdm_dolfinx.params import Param
from sdm_dolfinx.schemes.explicit import ExplicitScheme

#: the scheme's option: the restitution coefficient e
RESTITUTION = Param("restitution", 0.0, "restitution coefficient in [0, 1] (0: inelastic impact, 1: elastic "
                    "bounce)", type=float, low=0.0, high=1.0, expect="a number in [0, 1]", metavar="E", optional=True)


class PaoliSchatzman(ExplicitScheme):
    name = "paoli-schatzman"
    constrained = "(U^{n+1} + e U^{n-1})/(1 + e)"
    options = (RESTITUTION,)
    restitution = 0.0

    def set_parameters(self, restitution):
        e = float(restitution)
        self.restitution, self.mass_factor, self.factor = e, 1.0 + e, (1.0 + e) ** 0.5

    def rhs(self, integ, U, V, L, t):
        """b = M (2 U^n - (1 - e) U^{n-1} + dt^2 a^n) / dt^2, lifted; keeps U^{n-1}."""
        e, dt = self.restitution, integ.dt
        a = self.acceleration(integ, U, t)
        self._Um1 = U.array_r - dt * V.array_r + 0.5 * dt * dt * a.array_r
        Y = self._pred
        Y.array[:] = 2.0 * U.array_r - (1.0 - e) * self._Um1 + dt * dt * a.array_r
        return self.mass_rhs(integ, Y)

    def update(self, integ, X, U, V, t):
        """U^{n+1} = (1 + e) X - e U^{n-1}."""
        e = self.restitution
        self.finish(integ, (1.0 + e) * X.array_r - e * self._Um1, U, V, t)


SCHEME = PaoliSchatzman()
