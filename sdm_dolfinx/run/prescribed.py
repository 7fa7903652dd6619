"""Prescribed displacements in a run: a Problem's Dirichlet parts lifted at every step, their
reactions and the work of the reactions (:class:`~sdm_dolfinx.problems.dirichlet.DirichletPart`).

At every step the scheme's constrained iterate X takes, at a part's dofs, the value whose update
gives U^{n+1} = u_D(t_{n+1}) (:meth:`~sdm_dolfinx.schemes.base.Scheme.dirichlet_iterate`: the
midpoint scheme's (U^n + u_D(t_{n+1}))/2, backward Euler's u_D(t_{n+1})); the step matrix K keeps
its identity Dirichlet rows and the data enter through the lifting b - K g, recomputed. The
reaction is the residual R = K X - b at the Dirichlet rows (b before the lifting): the step's
balance M (V^{n+1} - V^n)/dt + A X = L + lam + R then holds at every row, R being the force the
support exerts on the body (positive along +axis). Its work R . (U^{n+1} - U^n) summed over the
steps is ``dirichlet_work``: the midpoint scheme conserves J - dirichlet_work to round-off without
impact. Nothing is kept between steps but what (U, V) hold, so a restart continues exactly.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.method import problem_data


#: a part's start velocity differs from the rate of its data at t = 0 when they differ by more than
#: this times the larger of the two (and of the first difference quotient): a forgotten ``velocity``
#: gives 1, data starting at rest about dt times the ratio of their third and second derivatives
#: (the second-order one-sided difference against the first quotient, both O(dt) then)
START_VELOCITY_RTOL = 0.1


def start_velocity_refusal(d, dt):
    """Why a Dirichlet part's ``velocity(x, 0)`` (0 when not given) cannot be the rate of its data at
    t = 0, or None (collective). The rate is (-3 u_D(0) + 4 u_D(dt) - u_D(2 dt)) / (2 dt), exact to
    O(dt^2); a part's velocity that is not its data's rate makes the midpoint rule's V^{n+1} =
    2 (U^{n+1} - U^n)/dt - V^n alternate from step to step, and the body feels it through the mass
    (a sine pushed without ``velocity``: energy off by half)."""
    for k, part in enumerate(d.problem.dirichlet_parts):
        u0, u1, u2 = (d.part_values(k, i * dt) for i in range(3))
        given = d.part_values(k, 0.0, rate=True)
        rate = (-3.0 * u0 + 4.0 * u1 - u2) / (2.0 * dt)
        ext = np.array([np.max(np.abs(rate - given), initial=0.0),
                        np.max(np.abs(rate), initial=0.0), np.max(np.abs(given), initial=0.0),
                        np.max(np.abs(u1 - u0), initial=0.0) / dt, np.max(np.abs(u0), initial=0.0) / dt])
        d.comm.Allreduce(MPI.IN_PLACE, ext, op=MPI.MAX)
        off, scale = ext[0], max(ext[1], ext[2], ext[3])
        if off > START_VELOCITY_RTOL * scale + 1e-12 * ext[4]:
            said = "not given (0: at rest)" if part.velocity is None else f"up to {ext[2]:.3g}"
            return (f"Dirichlet part {part.name!r}: its data move at t = 0 at up to {ext[1]:.3g} per unit time (from "
                    f"u_D at 0, dt and 2 dt), but its velocity(x, 0) is {said}, {off:.3g} apart: give velocity = "
                    f"du_D/dt")
    return None


class Prescribed:
    """The Dirichlet parts of one Integrator's run (its hooks are called by the Integrator)."""

    def refuse(self, integ):
        """The refusal of Dirichlet parts by the run's scheme or contact treatment when it does not take
        them, or of a part prescribing a frictional tangential dof, or None (collective)."""
        d, ts = integ.discretisation, integ.time_scheme
        if not ts.moving_dirichlet:
            return (f"scheme {integ.scheme!r} does not take Dirichlet parts (prescribed displacements, "
                    f"Problem.dirichlet_parts): use midpoint or backward-euler")
        if integ.contact == "nitsche":
            return ("contact 'nitsche' with Dirichlet parts is not supported (its boundary residual at Dirichlet rows "
                    "is dropped, so the reactions would miss it): use contact exact or penalty")
        if integ.friction is not None:      # a Dirichlet dof at a constrained vertex is a tangential one
            bs = d.W.dofmap.index_map_bs
            shared = d.comm.allreduce(int(np.count_nonzero(np.isin(d.ddofs // bs, d.cdofs // bs))), op=MPI.SUM)
            if shared:
                return (f"friction acts at constrained vertices where a Dirichlet part prescribes {shared} tangential "
                        f"components: leave the contact boundary out of the Dirichlet parts")
        return None

    def build(self, integ):
        """Once the step matrix exists: work vectors, where each part's dofs sit in ``ddofs``, and the
        (part, component) of each reaction column (:attr:`reaction_keys`)."""
        d = integ.discretisation
        self.b_dirichlet, self.KX = None, integ.K_full.createVecLeft()
        self.part_at = [np.searchsorted(d.ddofs, dofs) for dofs in d.part_dofs]
        shape = tuple(d.problem.shape)
        #: the (part index, component) of each reaction, in the order of the time series' columns
        self.reaction_keys = [(k, c) for k, part in enumerate(d.problem.dirichlet_parts) for c in part.axes(shape)]
        problem_data.refuse(d.problem, d.comm, start_velocity_refusal(d, integ.dt))

    def lift(self, integ, U, t):
        """The parts' values of the constrained iterate for the step from ``t`` (the scheme's
        ``dirichlet_iterate`` of u_D(t + dt) and U^n) into ``integ.gsys``, and the lifting
        ``integ.lift`` = K g (collective)."""
        d, ts = integ.discretisation, integ.time_scheme
        for k, dofs in enumerate(d.part_dofs):
            integ.gsys.array[dofs] = ts.dirichlet_iterate(d.part_values(k, t + integ.dt), U.array_r[dofs])
        integ.K_full.mult(integ.gsys, integ.lift)

    def unlifted(self, integ, b):
        """Keep the step's right-hand side at the Dirichlet rows before the lifting."""
        self.b_dirichlet = b.array_r[integ.discretisation.ddofs].copy()

    def reactions(self, integ, info, X, U, Un_D):
        """The step's reactions R = K X - b at the Dirichlet rows, summed per part and prescribed
        component, and their work R . (U^{n+1} - U^n) over the parts' dofs (``Un_D``: U^n at
        ``ddofs``), reduced over the ranks, into ``info`` (``reactions`` in the order of
        :attr:`reaction_keys`, ``dirichlet_work``)."""
        d = integ.discretisation
        integ.apply_step(X, self.KX)
        R = self.KX.array_r[d.ddofs] - self.b_dirichlet
        dU = U.array_r[d.ddofs] - Un_D
        local = np.zeros(len(self.reaction_keys) + 1)
        for i, (k, c) in enumerate(self.reaction_keys):
            at = self.part_at[k]
            local[i] = np.sum(R[at][d.part_components[k] == c])
        local[-1] = sum(float(np.dot(R[at], dU[at])) for at in self.part_at)
        total = d.comm.allreduce(local, op=MPI.SUM)
        info["reactions"], info["dirichlet_work"] = [float(v) for v in total[:-1]], float(total[-1])

    def destroy(self):
        self.KX.destroy()
