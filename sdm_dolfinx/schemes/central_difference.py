"""The explicit central-difference scheme (Newmark beta = 0, gamma = 1/2) with exact contact.

Newmark's explicit member in GetFEM's ``demo_dynamic_contact_1D.py`` form (see
:mod:`~sdm_dolfinx.schemes.explicit`): U^{n+1} = U^n + dt V^n + dt^2/2 a^n,
V^{n+1} = (U^{n+1} - U^n)/dt + dt/2 a^{n+1}, M a^n = L(t_n) - A U^n. Stable for
dt <= 2/omega_max (omega_max^2 the largest eigenvalue of M^-1 A): a larger dt is refused in one
line, with the bound measured on the run's matrices. Two enforcements of the exact contact, by
the mass (the choice D. Doyen, A. Ern, S. Piperno, SIAM J. Sci. Comput. 33 (2011) 223-249 discuss
for explicit schemes):

* a mass without mass at the contact dofs (``mass="redistributed"``, H. B. Khenous, P. Laborde,
  Y. Renard, Eur. J. Mech. A/Solids 27 (2008) 918-932): the massive dofs move explicitly, the
  massless ones Z (which must hold every constrained dof) solve the quasi-static contact
  problem of GetFEM's demo (version 0, ``mass_matrix_type >= 1``) at t_{n+1}:

      (A U^{n+1})_Z = L_Z + lam,   U^{n+1}_Z >= bound,  lam >= 0, complementary,

  an LCP whose matrix is A on Z and the identity on the massive dofs (their predicted
  U^{n+1}); their velocity is (U^{n+1} - U^n)/dt (GetFEM's). The CFL bound is measured on the
  massive dofs (M and A without the rows and columns of Z: a bound on the condensed system's);
* an invertible mass (``"standard"``, ``"row-sum"``): N. J. Carpenter, R. L. Taylor, M. G.
  Katona's forward-increment Lagrange multiplier method (Int. J. Numer. Meth. Eng. 32 (1991)
  103-128): the contact force lam^n at t_n is what keeps U^{n+1} admissible,

      M (U^{n+1} - U^n - dt V^{n-1/2}) / dt^2 = L - A U^n + lam^n,   U^{n+1} >= bound, complementary,

  the LCP with matrix M/dt^2 in X = U^{n+1} (the brief's 2M/dt^2 with the multiplier scaled by
  two: the same X; this scaling makes lam the force in the momentum balance M (V^{n+1/2} -
  V^{n-1/2}) = dt (L - A U^n + lam^n)). With the row-sum mass the LCP is diagonal: U^{n+1}_c =
  max(predicted, bound). GetFEM's demo refuses this combination; we offer it because it is
  the classical explicit contact of Carpenter et al.

A contact treatment (penalty, Nitsche) needs an invertible mass: its force at U^n joins a^n,
and the CFL bound includes its stiffness (linearised with every constraint active).
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.method import step_matrix as _step_matrix
from sdm_dolfinx.schemes.explicit import ExplicitScheme


class CentralDifference(ExplicitScheme):
    name = "central-difference"
    constrained = "U^{n+1}"
    massless_allowed = True
    treatments_allowed = True

    def refuse_massless(self, integ, massless):
        d = integ.discretisation
        if integ.contact != "exact":
            return (f"central-difference with contact {integ.contact!r} needs a mass at every dof; mass {d.mass!r} "
                    f"has dofs without mass: use mass 'standard' or 'row-sum'")
        free = d.comm.allreduce(int(np.count_nonzero(~np.isin(d.cdofs, massless))), op=MPI.SUM)
        if free:
            return (f"central-difference with mass {d.mass!r}: M has dofs without mass, but {free} constrained dofs "
                    f"have mass; the quasi-static contact step needs every constrained dof massless (or none: "
                    f"mass 'standard' or 'row-sum')")
        return None

    def step_matrix(self, integ):
        """Massless contact dofs Z: A on Z, the identity on the massive dofs; else None (M/dt^2)."""
        if not self.any_massless:
            return None
        d = integ.discretisation
        massive = np.setdiff1d(np.arange(integ.nW, dtype=np.int32), self.massless)
        return _step_matrix.identity_rows(d.A.copy(), massive)

    def rhs(self, integ, U, V, L, t):
        pred = self.predictor(integ, U, V, t)
        if not self.any_massless:
            return self.mass_rhs(integ, pred)       # (M/dt^2) X = (M/dt^2) pred + lam
        d, b, Z = integ.discretisation, integ.b, self.massless
        w = self._F                 # free: acceleration() is done for this step
        pred.copy(w)
        w.array[Z] = 0.0
        d.A.mult(w, b)              # (A U_massive)_Z
        L1 = integ.load(t + integ.dt) if integ.time_dependent else L      # the quasi-static step holds at t_{n+1}
        b.array[Z] = L1.array_r[Z] - b.array_r[Z]
        massive = np.ones(integ.nW, dtype=bool)
        massive[Z] = False
        b.array[massive] = pred.array_r[massive]
        return integ.lifted(b)

    def update(self, integ, X, U, V, t):
        self.finish(integ, X.array_r.copy(), U, V, t)


SCHEME = CentralDifference()
