"""What the Integrator reports of a state and of its last step: the energies J^h, the momenta, the
contact forces and active set (a mixin of :class:`~sdm_dolfinx.run.integrator.Integrator`)."""
import numpy as np

from sdm_dolfinx.method.dofs import reference_positions


class Measures:
    """The energies, momenta and step results of an Integrator (which sets ``discretisation``,
    ``solver``, ``block``, ``treatment``, ``finite_strain``, ``_mass``, ``_tmpW``, ``_rigid`` and
    ``load``)."""

    def initial_velocity(self, V):
        """The velocity unknown of this formulation from Vbar0 in W^h: Vbar0 itself, or (block
        variant) V0 in H^h with C V0 = B Vbar0 (condition (6) holds by construction)."""
        if not self.block:
            return V
        bv = self.discretisation.B.createVecLeft()
        self.discretisation.B.mult(V, bv)
        return self.discretisation.solve_C(bv)

    @property
    def active(self):
        """Which owned constrained dofs are active (the step solver's active set)."""
        return getattr(self.solver, "active", np.zeros(len(self.discretisation.cdofs), dtype=bool))

    @active.setter
    def active(self, mask):
        self.solver.active = mask

    @property
    def linear_its(self):
        """Linear (Krylov) iterations of the step solver since the start of the run."""
        return self.solver.total_linear_its

    @property
    def lam(self):
        """Nodal contact forces of the last step at the owned constrained dofs (>= 0 pushes),
        whatever the contact treatment."""
        return self.solver.lam

    def contact_energy(self, U, time=None):
        """The energy stored in the contact treatment at the state U at ``time`` (a moving obstacle's
        position; collective; 0.0 for the exact contact)."""
        if self.treatment is None:
            return 0.0
        rows = self.discretisation.obstacle_rows
        if time is not None and rows is not None and rows.moves:
            return float(self.treatment.energy(U, time))
        return float(self.treatment.energy(U))

    def energies(self, U, V, time=None):
        """(kinetic, potential) of the discrete energy J^h (Theorem 2); a time-dependent load
        enters the potential at ``time``, the time of the state (see :meth:`load`); a hyperelastic
        run's potential is int psi(C(U)) dx - U^T L."""
        d = self.discretisation
        t = self._tmpW
        if self.finite_strain:          # int psi(C(U)) dx: the hyperelastic strain energy
            pot = self.solver.strain_energy(U) - U.dot(self.load(time))
        else:
            d.A.mult(U, t)
            pot = 0.5 * U.dot(t) - U.dot(self.load(time))
        if self.block:
            cv = d.C.createVecLeft()
            d.C.mult(V, cv)
            kin = 0.5 * V.dot(cv)
        else:
            self._mass(V, t)
            kin = 0.5 * V.dot(t)
        return kin, pot

    def momentum(self, V, component):
        """Discrete momentum e^T M Vbar (or (B e)^T V) along ``component``."""
        d = self.discretisation
        if component not in self._rigid:
            self._rigid[component] = d.rigid_vector(component)
        e = self._rigid[component]
        if self.block:
            be = d.B.createVecLeft()
            d.B.mult(e, be)
            return V.dot(be)
        t = self._tmpW
        self._mass(e, t)
        return V.dot(t)


    def angular_momentum(self, U, V):
        """The discrete angular momentum sum_ab M_ab x_a x Vbar_b about the origin, x = X + U the current
        positions (X interpolated into W^h): the z component in 2-D, (x, y, z) in 3-D (M formulation;
        collective)."""
        d = self.discretisation
        if getattr(self, "_positions", None) is None:
            self._positions = reference_positions(d.W)
        gdim = d.problem.mesh.geometry.dim
        t = self._tmpW
        self._mass(V, t)
        x = (self._positions + U.array_r).reshape(-1, gdim)
        p = t.array_r.reshape(-1, gdim)
        if gdim == 2:
            return d.comm.allreduce(float(np.sum(x[:, 0] * p[:, 1] - x[:, 1] * p[:, 0])))
        return [float(v) for v in d.comm.allreduce(np.cross(x, p).sum(axis=0))]
