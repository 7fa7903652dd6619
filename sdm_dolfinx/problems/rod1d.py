"""The 1-D elastic rod of GetFEM's demo_dynamic_contact_1D.py, hitting an obstacle (closed form).

The benchmark of F. Dabaghi, A. Petrov, J. Pousin, Y. Renard (ESAIM: M2AN 48 (2014)
1147-1169) and of GetFEM's ``interface/tests/python/demo_dynamic_contact_1D.py``: the rod
[0, 1] (interval mesh, NX cells), rho = E = 1 (wave speed c = 1), fixed at x = 1 (u(1) = 0),
with frictionless unilateral contact u(0) >= 0 at x = 0, released from u0 = 1/2 - x/2 at rest
(v0 = 0). Dimensionless.

The equations: u_tt = u_xx in (0, 1), u(1, t) = 0 and, at x = 0, the Signorini conditions
u(0, t) >= 0, lambda(t) >= 0, u(0, t) lambda(t) = 0, lambda = -u_x(0, t) the contact stress
(the weak form (u_tt, w) + (u_x, w_x) = lambda w(0) for w(1) = 0: the force the obstacle
exerts along +x, the package's multiplier).

The exact solution (derived here as :func:`displacement` evaluates it): u is piecewise
linear in (x, t), with constant (u_x, u_t) in zones bounded by the characteristics x - t =
const and x + t = const; u is continuous, so across a right-going front [u_t] = -[u_x], across
a left-going one [u_t] = [u_x]. Write t = 3k + n + tau, phase n in {0, 1, 2}, tau in [0, 1):

* phase 0, flight: the free end x = 0 cannot carry the initial strain -1/2; the release front
  x = tau leaves it, behind it u_x = 0 and u_t = -1/2:  u = (1 - max(x, tau)) / 2. The front
  reaches x = 1 at tau = 1, where the rod is u = 0, u_t = -1/2 everywhere (u(0) = (1 - tau)/2
  > 0: no contact; the fixed end is already consistent: nothing reflects before tau = 1).
* phase 1, contact: the rod touches the obstacle at t = 3k + 1 at speed -1/2. u(0) = 0 sends
  the compression front x = tau (behind it u_t = 0, u_x = -1/2), the fixed end x = 1 the front
  x = 1 - tau (behind it u_t = 0, u_x = +1/2); where both have passed (tau > 1/2),
  u_t = +1/2, u_x = 0:  u = -min(x, tau)/2 where tau <= 1 - x, (max(x, tau) - 1)/2 elsewhere.
  At x = 0: u = 0 and lambda = -u_x = 1/2 for the whole phase; at tau = 1 the front from x = 1
  arrives (u = 0, u_t = +1/2 everywhere) and the rod leaves the obstacle at t = 3k + 2
  (lambda would turn negative).
* phase 2, flight: the fixed end sends x = 1 - tau, behind it u_t = 0, u_x = -1/2:
  u = min(tau, 1 - x)/2; u(0) = tau/2 > 0 and u_x(0) = 0 (free). At tau = 1, u = (1 - x)/2 at
  rest: the initial state. The motion is periodic of period 3.

In every zone one of u_t, u_x is +-1/2 and the other 0: the energy 1/2 int (u_t^2 + u_x^2) dx
is 1/8 at all times. Contact phases [3k + 1, 3k + 2) at the stress 1/2, impacts at speed -1/2,
releases at +1/2. On a characteristic, the zone is chosen as GetFEM's ``uExact`` does
(tau < x: ahead of the front from x = 0; tau <= 1 - x: ahead of the front from x = 1), so the
functions below equal ``uExact`` everywhere (the contact end at t = 0 is behind the release
front: u_t(0, 0) = -1/2, as at every t > 0).

Defaults as GetFEM's demo: NX = 20, dt = 2e-3, T = 12 (four periods).
"""
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.problems import base as _problem
from sdm_dolfinx.problems.base import Param, Problem, ProblemSpec
from sdm_dolfinx.problems.exact import ExactSolution, coordinate

#: the period of the motion and the contact phase within it: [1, 2) + 3k
PERIOD = 3.0
#: the energy 1/2 int (u_t^2 + u_x^2) dx, constant
ENERGY = 0.125


def _phase(t):
    """(phase n in {0, 1, 2}, tau in [0, 1)) of the times ``t``: t = 3k + n + tau."""
    tp = np.mod(np.asarray(t, dtype=float), PERIOD)
    n = np.floor(tp)
    return n, tp - n


def displacement(x, t):
    """u(x, t) of the rod (x: positions along it, any shape broadcast against t)."""
    n, tau = _phase(t)
    phase0 = 0.5 * (1.0 - np.maximum(x, tau))
    phase1 = np.where(tau <= 1.0 - x, -0.5 * np.minimum(x, tau), 0.5 * (np.maximum(x, tau) - 1.0))
    phase2 = 0.5 * np.minimum(tau, 1.0 - x)
    return np.select([n == 0, n == 1], [phase0, phase1], phase2)


def _zones(x, t):
    """(phase, ahead of the front from x = 0, ahead of the front from x = 1)."""
    n, tau = _phase(t)
    return n, tau < x, tau <= 1.0 - x


def velocity(x, t):
    """u_t(x, t): -1/2, 0 or 1/2 by zone."""
    n, a0, a1 = _zones(x, t)
    phase0 = np.where(a0, 0.0, -0.5)
    phase1 = np.where(a1, np.where(a0, -0.5, 0.0), np.where(a0, 0.0, 0.5))
    phase2 = np.where(a1, 0.5, 0.0)
    return np.select([n == 0, n == 1], [phase0, phase1], phase2)


def strain(x, t):
    """u_x(x, t): -1/2, 0 or 1/2 by zone."""
    n, a0, a1 = _zones(x, t)
    phase0 = np.where(a0, -0.5, 0.0)
    phase1 = np.where(a1, np.where(a0, 0.0, -0.5), np.where(a0, 0.5, 0.0))
    phase2 = np.where(a1, 0.0, -0.5)
    return np.select([n == 0, n == 1], [phase0, phase1], phase2)


class RodExact(ExactSolution):
    """The rod's closed form (module docstring), in the :class:`ExactSolution` interface."""
    contact_point = np.zeros(3)
    energy = ENERGY
    period = PERIOD

    def __init__(self, horizon=12.0):
        self.horizon = float(horizon)

    def displacement(self, x, t):
        return displacement(coordinate(x), t)

    def velocity(self, x, t):
        return velocity(coordinate(x), t)

    def strain(self, x, t):
        return strain(coordinate(x), t)

    def contact_stress(self, t):
        """lambda(t) = -u_x(0, t): 1/2 on [3k + 1, 3k + 2), else 0."""
        return -strain(np.zeros_like(np.asarray(t, dtype=float)), t) + 0.0

    def intervals(self, T):
        return [(PERIOD * k + 1.0, PERIOD * k + 2.0) for k in range(int(np.ceil(max(T, 0.0) / PERIOD)) + 1)
                if PERIOD * k + 1.0 < T]


def exact(problem):
    """The closed form of a rod1d Problem (it has no parameter besides the mesh)."""
    return RodExact(horizon=SPEC.defaults["T"])


def flux(u):
    """The stress (a flux vector of the scalar u): sigma(u) = E du/dx, E = 1."""
    return ufl.grad(u)


def _build(comm, NX):
    """The rod Problem for declared values (see :data:`SPEC`)."""
    msh = dmesh.create_interval(comm, NX, [0.0, 1.0])
    tol = 1e-10

    def at_contact(x):
        return np.abs(x[0]) <= tol

    points = np.sort(dmesh.locate_entities_boundary(msh, 0, at_contact)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, 0, points, np.ones_like(points)))(1)
    zero = fem.Constant(msh, PETSc.ScalarType(0.0))      # no load (l must be a form)
    return _problem.Problem(
        name="rod1d", mesh=msh, shape=(), rho=1.0,
        a=lambda u, w: ufl.inner(flux(u), ufl.grad(w)) * ufl.dx,
        l=lambda w: zero * w * ufl.dx,
        stress=flux,
        u0=lambda x: 0.5 - 0.5 * x[0],
        v0=lambda x: np.zeros(x.shape[1]),
        constraint_vertices=lambda m: dmesh.locate_entities(m, 0, at_contact),
        lower_bound=lambda x: np.zeros(x.shape[1]),
        # the point x = 0: its measure is 1, so the stress is the nodal multiplier
        constraint_measure=lambda q: q * ds_c,
        dirichlet_facets=lambda m: dmesh.locate_entities_boundary(m, 0, lambda x: np.abs(x[0] - 1.0) <= tol),
        dirichlet_value=lambda x: np.zeros(x.shape[1]),
        probe=(0.0, 0.0),
        extra_columns=("contact_force", "elastic"),
        parameters={"NX": NX, "h": 1.0 / NX, "L": 1.0, "E": 1.0, "rho": 1.0, "c": 1.0, "period": PERIOD,
                    "energy": ENERGY, "contact_stress": 0.5, "probe": "the contact point x = 0"},
        units={"all": "dimensionless (length 1, wave speed 1)"},
    )


#: the rod's parameters, declared once (command line, TOML, run.json, rebuild)
PARAMS = (
    Param("NX", 20, "cells of the interval mesh of [0, 1], h = 1/NX (GetFEM's demo: 20)", type=int, low=1),
)


def estimate(values):
    """The interval mesh the parameter ``values`` make (for the memory estimate of a run)."""
    nx = values["NX"]
    return {"vertices": nx + 1, "edges": nx, "cells": nx, "value_size": 1, "by": ("NX",)}


SPEC = ProblemSpec(
    name="rod1d", build=_build, params=PARAMS, estimate=estimate, doc=(__doc__ or "").strip(), exact=exact,
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 2e-3, "T": 12.0, "time_unit": "dimensionless"},
)


def problem(comm: MPI.Comm = MPI.COMM_WORLD, **values: Any) -> Problem:
    """The rod; ``values`` are :data:`PARAMS` (``NX``)."""
    return SPEC.problem(comm, **values)
