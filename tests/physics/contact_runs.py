"""Runs of a contact treatment (penalty, Nitsche) through the Integrator, kept step by step:
the helper of tests/physics/test_penalty.py and test_nitsche.py (not a test module)."""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.run.integrator import Integrator


class Run:
    """One problem, pair, scheme and contact treatment; :meth:`advance` steps and records.

    Attributes after :meth:`advance`: ``energy`` (kinetic + potential + contact energy at each
    recorded state), ``parts`` (the three terms), ``states`` (the owned U arrays, if ``keep``),
    ``infos`` (the steps' infos), ``lam`` (the owned lam after each step), ``t``.
    """

    def __init__(self, problem, pair, dt, contact, options=None, scheme="midpoint", mass=None):
        self.d = Discretisation(problem, pair, mass=mass)
        self.integ = Integrator(self.d, scheme=scheme, dt=dt, contact=contact, contact_options=options or {})
        self.treatment = self.integ.treatment
        self.U, V = self.d.initial_state()
        self.V = self.integ.initial_velocity(V)
        self.dt = dt
        self.parts, self.energy, self.states, self.infos, self.lam, self.t = [], [], [], [], [], [0.0]
        self._record_energy()

    def _record_energy(self):
        """(kinetic, potential, contact energy) of the state, and their sum."""
        kin, pot = self.integ.energies(self.U, self.V)
        self.parts.append((kin, pot, self.integ.contact_energy(self.U)))
        self.energy.append(sum(self.parts[-1]))

    def advance(self, T, keep=False):
        """Steps up to time T (from the current time), recording each state."""
        if keep and not self.states:
            self.states.append(self.U.array.copy())
        n0 = len(self.infos)
        for n in range(n0, n0 + int(round((T - self.t[-1]) / self.dt))):
            self.infos.append(self.integ.step(self.U, self.V, n, n * self.dt))
            self.lam.append(np.array(self.integ.lam, dtype=float))
            self._record_energy()
            self.t.append((n + 1) * self.dt)
            if keep:
                self.states.append(self.U.array.copy())
        return self

    def global_sum(self, local):
        return float(self.d.comm.allreduce(float(local), op=MPI.SUM))

    def destroy(self):
        self.integ.destroy()
