"""The classical Newmark scheme (beta = 1/4, gamma = 1/2) with the constraint on U^{n+1}.

N. M. Newmark, J. Eng. Mech. Div. 85 (1959) 67-94, as D. Doyen, A. Ern, S. Piperno, *Time-
integration schemes for the finite element dynamic Signorini problem*, SIAM J. Sci. Comput.
33 (2011) 223-249, use it in their class "standard mass, implicit": the contact is the exact
Signorini condition on the end-of-step displacement, with a contact force lam^{n+1} in the
equation at t_{n+1},

    M a^{n+1} + A U^{n+1} = L(t_{n+1}) + lam^{n+1},    U^{n+1} >= bound, lam^{n+1} >= 0, complementary,
    U^{n+1} = U^n + dt V^n + dt^2/2 ((1 - 2 beta) a^n + 2 beta a^{n+1}),
    V^{n+1} = V^n + dt ((1 - gamma) a^n + gamma a^{n+1}).

Eliminating a^{n+1} = (U^{n+1} - Utilde)/(beta dt^2), Utilde = U^n + dt V^n + dt^2 (1 - 2 beta)/2 a^n,
each step is the LCP in X = U^{n+1}

    (M / (beta dt^2) + A) X = L + M Utilde / (beta dt^2) + lam

(for beta = 1/4 the midpoint scheme's matrix 4 M/dt^2 + A). Choices taken where the literature
leaves one open:

* the state: the acceleration a^n is kept between steps (``stateful``), defined by the
  kinematic relation above, so that M a^{n+1} = L + lam^{n+1} - A U^{n+1} holds exactly and
  only products with M appear: a singular M (the singular dynamic method, a redistributed
  mass) needs no inverse;
* the initial acceleration: M a^0 = L(0) - A U^0 + lam^0, solved in the least-squares sense
  (:func:`~sdm_dolfinx.method.step_mass.least_squares_acceleration`): for a singular M the part
  of the force in ker M (the massless dofs' unbalanced force) is dropped, as GetFEM's
  ``demo_dynamic_contact_1D.py`` zeroes the contact node's M a^0. The initial contact force
  lam^0 is the compressive part (A U^0 - L)_+ of the force at the constrained dofs that U^0
  puts on their bound (within :data:`TOUCH_RTOL`), 0 elsewhere: a body starting at rest in
  equilibrium on the obstacle starts with a^0 = 0 (the block), a body starting off it with
  M a^0 = L - A U^0 (the rod); for a diagonal M this nodal rule is the solution of the
  acceleration's LCP (a^0_c >= 0, lam^0 >= 0, complementary);
* the velocity of a dof without mass (a zero row of M: the redistributed mass's contact dofs)
  is (U^{n+1} - U^n)/dt, as GetFEM's demo takes it: Newmark's kinematic velocity, 2 (U^{n+1} -
  U^n)/dt - V^n there, alternates in sign from step to step (measured +-25 at the rod's contact
  node, impact speed 1/2); neither carries kinetic energy or enters the dynamics (M V only). The
  singular dynamic method's M has no zero row: its kernel keeps the kinematic velocity, as the
  midpoint scheme does;
* a contact treatment (penalty, Nitsche) enters as lam^{n+1} = its force at U^{n+1};
* a hyperelastic material (``finite_strain = "endpoint"``): A U is the internal force F_int(U) of the
  stress P(F(U)) at the step's end (for HHT also at U^n), for comparison with the energy-momentum
  midpoint scheme: Newmark's energy is not conserved then, even without contact.

With gamma = 1/2 and beta = 1/4, (U^{n+1} - U^n)/dt = (V^n + V^{n+1})/2 and M (V^{n+1} - V^n) =
dt (M a^n + M a^{n+1})/2: without contact the energy J = 1/2 V.M V + 1/2 U.A U - U.L is
conserved exactly (J^{n+1} - J^n = (U^{n+1} - U^n).(lam^n + lam^{n+1})/2 with contact, which
the constraint on U^{n+1} does not make vanish: the "standard mass, implicit" class's energy
error and contact-stress oscillations of Doyen et al.).
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.method import step_mass
from sdm_dolfinx.schemes.base import Scheme

#: a constrained dof whose initial displacement is within this (times 1 + max |bound|) of its
#: bound touches the obstacle at t = 0 (the scale of the Discretisation's INITIAL_TOL)
TOUCH_RTOL = 1e-8


class Newmark(Scheme):
    """Newmark's scheme (beta, gamma) as the HHT-alpha family with alpha = 0 (module docstring)."""
    name = "newmark"
    constrained = "U^{n+1}"
    load_theta = 1.0                # L(t_{n+1})
    stateful = True
    beta, gamma, hht = 0.25, 0.5, 0.0
    factor = 2.0                    # c_M = (factor/dt)^2 = 1/(beta dt^2)
    finite_strain = "endpoint"      # a hyperelastic material: A U becomes F_int(U), the stress P(F(U))

    def refuse(self, integ):
        return self.needs_m_formulation(integ)

    def coefficients(self, dt):
        """K = M/(beta dt^2) + (1 + alpha) A."""
        return 1.0 / (self.beta * dt * dt), 1.0 + self.hht

    def start(self, integ, U, V, t):
        """The state {"a": a^0, "Ut": work vector}: M a^0 = L(t) - A U + (the treatment's force)."""
        d = integ.discretisation
        F = d.A.createVecLeft()
        self._internal(integ, U, F)
        F.scale(-1.0)
        F.axpy(1.0, integ.load(t) if integ.time_dependent else d.L)
        if integ.treatment is not None:
            force = F.duplicate()
            integ.treatment.force(U, force)
            F.axpy(1.0, force)
            force.destroy()
        else:                       # lam^0: the obstacle carries the compression where U^0 touches it
            scale = 1.0 + d.comm.allreduce(float(np.max(np.abs(d.lb), initial=0.0)), op=MPI.MAX)
            touch = U.array_r[d.cdofs] - d.lb <= TOUCH_RTOL * scale
            F.array[d.cdofs] += np.where(touch, np.maximum(-F.array_r[d.cdofs], 0.0), 0.0)
        a = step_mass.least_squares_acceleration(d, F)
        F.destroy()
        self.massless = step_mass.massless_dofs(d.M)
        return {"a": a, "Ut": a.duplicate(), "AU": a.duplicate()}

    @staticmethod
    def _internal(integ, U, out):
        """out <- the internal force at U: A U, or a hyperelastic run's F_int(U) (the step solver's forms)."""
        if integ.finite_strain:
            integ.solver.forms.force(U, U, out)
        else:
            integ.discretisation.A.mult(U, out)

    def rhs(self, integ, U, V, L, t):
        """b = L + M Utilde / (beta dt^2) + alpha A U^n (alpha = 0: Newmark), lifted."""
        s, dt, b = integ.state, integ.dt, integ.b
        Ut = s["Ut"]
        U.copy(Ut)
        Ut.axpy(dt, V)
        Ut.axpy(dt * dt * (1.0 - 2.0 * self.beta) / 2.0, s["a"])
        integ.mass_mult(Ut, b)
        b.scale(1.0 / (self.beta * dt * dt))
        b.axpy(1.0, L)
        if self.hht:
            self._internal(integ, U, s["AU"])
            b.axpy(self.hht, s["AU"])
        return integ.lifted(b)

    def update(self, integ, X, U, V, t):
        """a^{n+1} = (X - Utilde)/(beta dt^2), V^{n+1} = V^n + dt ((1-gamma) a^n + gamma a^{n+1}), U^{n+1} = X."""
        s, dt = integ.state, integ.dt
        a, Ut = s["a"], s["Ut"]
        a_new = (X.array - Ut.array) / (self.beta * dt * dt)
        V.array[:] += dt * ((1.0 - self.gamma) * a.array + self.gamma * a_new)
        Z = self.massless
        V.array[Z] = (X.array[Z] - U.array[Z]) / dt
        a.array[:] = a_new
        U.array[:] = X.array

    def destroy(self, integ):
        for v in (integ.state or {}).values():
            v.destroy()


SCHEME = Newmark()
