"""What the explicit schemes share: the mass solver, the free acceleration, the CFL check.

The explicit schemes (central differences, Paoli-Schatzman, Taylor-Flanagan) are Newmark's
explicit member (beta = 0, gamma = 1/2) in the velocity-Verlet form GetFEM's
``demo_dynamic_contact_1D.py`` uses: with a^n = M^-1 (L(t_n) - A U^n) the free acceleration,

    U^{n+1} = U^n + dt V^n + dt^2/2 a^n (+ the contact correction),
    V^{n+1} = (U^{n+1} - U^n)/dt + dt/2 a^{n+1},

so V^n - dt/2 a^n = (U^n - U^{n-1})/dt: (U^n, V^n) hold U^{n-1} and no other state is kept
(a restart from U and V continues the same sequence). V^{n+1} leaves out the contact force at
t_{n+1}, which the next step finds: a dof resting on the obstacle shows |V| = dt/2 |a| = O(dt). Each step is one LCP with the matrix
c M / dt^2 (no stiffness: each step costs a solve with M) or, with massless contact dofs, a
quasi-static one (:mod:`~sdm_dolfinx.schemes.central_difference`).

M^-1: a diagonal M (the row-sum lumped mass) is divided by, any other factorised once
(:class:`~sdm_dolfinx.method.step_mass.MassSolver`). The step is stable for dt <= 2/omega_max,
omega_max^2 the largest eigenvalue of M^-1 A (plus the contact treatment's stiffness), which
:meth:`ExplicitScheme.prepare` measures on the run's matrices and refuses beyond.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.method import step_mass
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.schemes.base import Scheme

#: dt is refused beyond CFL_SAFETY x 2/omega_max (1: the stability bound itself, measured to
#: SLEPc's tolerance 1e-10)
CFL_SAFETY = 1.0
#: the depth (times 1 + max |bound|) below the bounds at which a contact treatment's force is
#: linearised for the CFL bound: every constraint active there, the force affine
DEEP = 1e6


class ExplicitScheme(Scheme):
    """An explicit scheme: K = mass_factor M / dt^2, the free acceleration, the CFL check.

    Attributes:
        mass_factor: c in K = c M / dt^2.
        massless_allowed: the scheme runs with dofs without mass (then the constrained ones).
        treatments_allowed: the scheme runs with a contact treatment (its force at U^n).
    """
    explicit = True
    load_theta = 0.0                # the step's equation holds at t_n: M a^n = L(t_n) - A U^n + lam^n
    mass_factor = 1.0
    factor = 1.0                    # c_M = (factor/dt)^2 = mass_factor/dt^2
    massless_allowed = False
    treatments_allowed = False

    # ------------------------------------------------------------------ set-up
    def refuse(self, integ):
        d, name = integ.discretisation, self.name
        if self.needs_m_formulation(integ):
            return self.needs_m_formulation(integ)
        if not d.pair.standard:
            return (f"scheme {name!r} is explicit and needs M^-1; the singular dynamic method's M = B^T C^-1 B "
                    f"(pair {d.pair.name}) is singular away from the contact boundary: use a standard pair (P1/P1, "
                    f"P2/P2) with mass 'standard', 'row-sum' or 'redistributed', or an implicit scheme")
        if integ.friction is not None:
            return (f"scheme {name!r} has no frictional step: friction needs an implicit scheme (midpoint, "
                    f"backward-euler, newmark, hht)")
        if integ.contact != "exact" and not self.treatments_allowed:
            return (f"scheme {name!r} enforces the contact itself (its impact law): contact must be 'exact', "
                    f"not {integ.contact!r}")
        return None

    def refuse_massless(self, integ, massless):
        """The refusal of a mass with the (local) massless dofs ``massless``, or None."""
        count = integ.discretisation.comm.allreduce(len(massless), op=MPI.SUM)
        return (f"scheme {self.name!r} imposes its impact law on the velocity of the contact dofs, and mass "
                f"{integ.discretisation.mass!r} has {count} dofs without mass: use mass 'standard' or "
                f"'row-sum', or central-difference for a massless contact boundary")

    def setup(self, integ):
        """The massless dofs (refused unless the scheme allows them) and the mass solver."""
        d = integ.discretisation
        massless = np.setdiff1d(step_mass.massless_dofs(d.M), d.ddofs).astype(np.int32)
        if d.comm.allreduce(len(massless), op=MPI.SUM):
            refused = self.refuse_massless(integ, massless)
            if refused:
                raise DiscretisationError(refused)
        self.massless = massless
        self.any_massless = d.comm.allreduce(len(massless), op=MPI.SUM) > 0
        integ.mass_solver = step_mass.MassSolver(d, massless)
        self._a, self._a_at, self._pred = d.A.createVecLeft(), None, d.A.createVecLeft()
        self._F, self._force = d.A.createVecLeft(), d.A.createVecLeft()

    def coefficients(self, dt):
        """K = mass_factor M / dt^2 (no stiffness)."""
        return self.mass_factor / (dt * dt), 0.0

    def prepare(self, integ):
        """The CFL check (DiscretisationError beyond the bound); a contact treatment's step is
        one solve with M (:class:`ForceStep`), its force evaluated at U^n."""
        if integ.treatment is not None:
            integ.solver = ForceStep(integ, self)
        lam_max = step_mass.largest_eigenvalue(self._stiffness(integ), integ.mass_solver, self._a)
        omega = float(np.sqrt(max(lam_max, 0.0)))
        integ.cfl = {"omega_max": omega, "dt_max": 2.0 / omega if omega > 0 else float("inf")}
        refused = cfl_refusal(self.name, integ.dt, integ.cfl["dt_max"], lam_max, integ.treatment is not None)
        if refused:
            raise DiscretisationError(refused)

    def _stiffness(self, integ):
        """y = K x, K = A (+ the contact treatment's stiffness, all constraints active), zero
        rows and columns at the Dirichlet and massless dofs."""
        d, zero, tr = integ.discretisation, integ.mass_solver.zero, integ.treatment
        t = d.A.createVecLeft()
        if tr is not None:
            scale = 1.0 + d.comm.allreduce(float(np.max(np.abs(d.lb), initial=0.0)), op=MPI.MAX)
            deep, f0, f1 = t.duplicate(), t.duplicate(), t.duplicate()
            deep.set(-DEEP * scale)
            tr.force(deep, f0)

        def apply(x, y):
            t.array[:] = x.array_r
            t.array[zero] = 0.0
            d.A.mult(t, y)
            if tr is not None:          # the force's derivative at the deep state: -(f(X0 + t) - f(X0))
                t.axpy(1.0, deep)
                tr.force(t, f1)
                y.axpy(-1.0, f1)
                y.axpy(1.0, f0)
            y.array[zero] = 0.0
        return apply

    def destroy(self, integ):
        for v in (self._a, self._pred, self._F, self._force):
            v.destroy()
        integ.mass_solver.destroy()

    # ------------------------------------------------------------------ a step
    def acceleration(self, integ, U, t):
        """a = M^-1 (L(t) - A U + the contact treatment's force at U), zero at the Dirichlet and
        massless dofs (kept: the end of one step is the start of the next)."""
        d, F, key = integ.discretisation, self._F, U.array_r
        hit = (self._a_at is not None and np.array_equal(self._a_at[1], key)
               and (not integ.time_dependent or abs(self._a_at[0] - t) <= 1e-9 * integ.dt))
        if d.comm.allreduce(hit, op=MPI.LAND):          # every rank, or none, skips the collective work
            return self._a
        d.A.mult(U, F)
        F.scale(-1.0)
        F.axpy(1.0, integ.load(t) if integ.time_dependent else d.L)
        if integ.treatment is not None:
            integ.treatment.force(U, self._force)
            F.axpy(1.0, self._force)
            integ.solver.lam = np.asarray(integ.treatment.nodal_forces(U), dtype=float).copy()   # the reported lam
        integ.mass_solver.solve(F, self._a)
        self._a_at = (t, key.copy())
        return self._a

    def predictor(self, integ, U, V, t):
        """U^n + dt V^n + dt^2/2 a^n (a work vector of this scheme)."""
        dt, pred = integ.dt, self._pred
        U.copy(pred)
        pred.axpy(dt, V)
        pred.axpy(0.5 * dt * dt, self.acceleration(integ, U, t))
        return pred

    def mass_rhs(self, integ, Y):
        """b = M Y / dt^2, lifted: the step's K X = b + lam has X = Y / mass_factor without contact."""
        integ.mass_mult(Y, integ.b)
        integ.b.scale(1.0 / (integ.dt * integ.dt))
        return integ.lifted(integ.b)

    def finish(self, integ, U1, U, V, t):
        """U^{n+1} = U1 and V^{n+1} = (U^{n+1} - U^n)/dt + dt/2 a^{n+1}, in place."""
        dt = integ.dt
        Un = U.array.copy()
        U.array[:] = U1
        a = self.acceleration(integ, U, t + dt)
        V.array[:] = (U.array - Un) / dt + 0.5 * dt * a.array_r


def cfl_refusal(name, dt, dt_max, lam_max, with_treatment):
    """The one-line refusal of a dt beyond CFL_SAFETY x the CFL bound, or None."""
    if dt <= CFL_SAFETY * dt_max:
        return None
    what = "M^-1 (A + the contact treatment's stiffness)" if with_treatment else "M^-1 A"
    return (f"scheme {name!r}: dt = {dt:.6g} exceeds the CFL bound 2/omega_max = {dt_max:.6g} (omega_max^2 = "
            f"{lam_max:.6g}, the largest eigenvalue of {what}, measured on this run's matrices); take dt <= "
            f"{dt_max:.6g} or an implicit scheme")


class ForceStep:
    """The step solver of an explicit scheme with a contact treatment: X = K^-1 b (one solve
    with M), the treatment's force at U^n already in b; ``lam`` that force at the constrained dofs."""

    def __init__(self, integ, scheme):
        self.integ, self.scheme = integ, scheme
        self.lam = np.zeros(len(integ.discretisation.cdofs))
        self.total_linear_its = 0

    @property
    def active(self):
        return self.lam > 0.0

    @active.setter
    def active(self, mask):
        pass                            # nothing to warm-start

    def solve(self, b, X):
        integ = self.integ
        d = integ.discretisation
        integ.mass_solver.solve(b, X)
        X.scale(integ.dt * integ.dt / self.scheme.mass_factor)
        X.array[d.ddofs] = b.array_r[d.ddofs]
        self.total_linear_its += 1
        return {"its": 1, "n_active": d.comm.allreduce(int(np.count_nonzero(self.lam > 0.0)), op=MPI.SUM)}

    def destroy(self):
        pass
