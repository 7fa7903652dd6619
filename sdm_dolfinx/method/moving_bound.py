"""A moving obstacle: the bound of each step, and the work of the contact force on its motion.

A Problem with ``moving_bound`` declares ``lower_bound(x, t)``: u_c(a_i) >= g_i(t). Before every
step :meth:`MovingBound.before_step` evaluates g at t_n and t_{n+1} (each time once: the end of
one step is the start of the next) and writes the scheme's step bound
(:meth:`~sdm_dolfinx.schemes.base.Scheme.step_bound`: midpoint (g(t_n) + g(t_{n+1})) / 2,
backward Euler g(t_{n+1})) in place into the discretisation's ``lb``, the array every step solver
reads (the semi-smooth Newton, its Schur complement and active-set systems, SNES VI's variable
bounds, the frictional solvers: each keeps a reference to it, checked by :meth:`refusal_of_solver`).
After the solve :meth:`after_solve` writes g(t_{n+1}) there (and into ``blb``, the constrained
boundary's dofs): between steps the bounds are those of the state (gaps, the next step), and
returns the step's obstacle work sum_i lam_i (g_i(t_{n+1}) - g_i(t_n)). Why that work, and why the
mean of the bounds for the midpoint scheme: :mod:`sdm_dolfinx.schemes.midpoint`.
"""
from typing import Any

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.method import problem_data
from sdm_dolfinx.method.errors import DiscretisationError


def moves(discretisation: Any) -> bool:
    """The discretisation's Problem declares a moving bound, and it constrains something."""
    return bool(getattr(discretisation.problem, "moving_bound", False)) and discretisation.num_constraints > 0


def refusal(discretisation, scheme, contact):
    """The one-line refusal of a moving bound by a scheme that does not say when it imposes it, or by a
    contact treatment (penalty, Nitsche: they evaluate the bound once), or None (also without one)."""
    if not moves(discretisation):
        return None
    name = discretisation.problem.name
    if scheme.bound_weight is None:
        return (f"problem {name!r} has a moving bound (moving_bound=True), which scheme {scheme.name!r} does not "
                f"take: use the midpoint or backward-euler scheme")
    if contact != "exact":
        return (f"problem {name!r} has a moving bound, which contact {contact!r} does not take (it evaluates the "
                f"bound once): use contact 'exact'")
    return None


def refusal_of_solver(discretisation, solver):
    """The one-line refusal when the step solver keeps its own copy of the bounds on some rank (it
    would not see the bound of each step), or None. Collective (a rank without constraints has
    nothing to share)."""
    d = discretisation
    lb = getattr(solver, "lb", None)
    own = len(d.lb) > 0 and (lb is None or not np.shares_memory(np.asarray(lb), d.lb))
    if not d.comm.allreduce(bool(own), op=MPI.LOR):
        return None
    return (f"problem {d.problem.name!r} has a moving bound, and step solver {type(solver).__name__} keeps its own "
            f"copy of the bounds: it cannot take the bound of each step")


class MovingBound:
    """The bound of each step of a Discretisation whose Problem declares ``moving_bound`` (for any
    other, its methods do nothing: :attr:`on` is False).

    Raises:
        DiscretisationError: the step ``solver`` keeps its own copy of the bounds (:func:`refusal_of_solver`).
    """

    def __init__(self, discretisation, scheme, dt, solver):
        self.d, self.scheme, self.dt = discretisation, scheme, float(dt)
        self.on = moves(discretisation)
        refused = self.on and refusal_of_solver(discretisation, solver)
        if refused:
            raise DiscretisationError(refused)
        self._cache = {}
        self._g = None

    def bounds_at(self, t):
        """(g at the constrained dofs, g at the constrained boundary's dofs) at time ``t`` (collective)."""
        d = self.d
        if t not in self._cache:
            self._cache[t] = (problem_data.bound(d.problem, d.cx, d.comm, t),
                              problem_data.bound(d.problem, d.bx, d.comm, t))
        return self._cache[t]

    def before_step(self, n, t):
        """Write the step bound of the step n (from t to t + dt) into ``lb`` (t_{n+1} = (n + 1) dt
        when t = n dt, so that it is the next step's t_n exactly)."""
        if not self.on:
            return
        t1 = (n + 1) * self.dt if t == n * self.dt else t + self.dt
        (g0, _), (g1, blb1) = self.bounds_at(t), self.bounds_at(t1)
        self._cache = {t1: (g1, blb1)}
        self._g = (g0, g1, blb1)
        self.d.lb[:] = self.scheme.step_bound(g0, g1)      # in place: the array the step solver reads

    def after_solve(self, lam, info):
        """Put the bounds at t_{n+1} into ``lb`` and ``blb``, and the step's obstacle work
        sum_i lam_i (g_i(t_{n+1}) - g_i(t_n)) (reduced over the ranks) into ``info["obstacle_work"]``."""
        if not self.on:
            return
        g0, g1, blb1 = self._g
        self.d.lb[:], self.d.blb[:] = g1, blb1
        info["obstacle_work"] = self.d.comm.allreduce(float(np.dot(lam, g1 - g0)), op=MPI.SUM)
