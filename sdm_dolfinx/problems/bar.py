"""An elastic bar hitting a rigid obstacle with an initial velocity: one impact (closed form).

The first 1-D benchmark of D. Doyen, A. Ern, S. Piperno, *Time-integration schemes for the
finite element dynamic Signorini problem*, SIAM J. Sci. Comput. 33 (2011) 223-249 (HAL
hal-00440128), the one on which they show the spurious oscillations of the contact stress:
the bar [0, L] (interval mesh, NX cells), density rho, Young's modulus E (c = sqrt(E/rho)),
free at x = L, moves at the speed v toward a rigid obstacle at the distance ``gap`` from its
end x = 0: u0 = 0, v0 = -v, frictionless contact u(0, t) >= -gap.

The equations: rho u_tt = E u_xx in (0, L), E u_x(L, t) = 0 and, at x = 0, the Signorini
conditions u(0, t) + gap >= 0, lambda(t) >= 0, (u(0, t) + gap) lambda(t) = 0, with the contact
stress lambda = -E u_x(0, t) (the force per unit cross-section the obstacle exerts along +x,
the package's multiplier: the weak form (rho u_tt, w) + (E u_x, w_x) = lambda w(0)).

The exact solution (d'Alembert; :func:`displacement` evaluates it). Let t0 = gap / v (the
impact), s = t - t0, t1 = t0 + 2L/c (the release). u is piecewise linear in (x, t); u is
continuous, so across a right-going front [u_t] = -c [u_x], across a left-going one
[u_t] = c [u_x]:

* before the impact the bar flies rigidly: u = -v t = -gap - v s;
* at t0 the end x = 0 stops; the compression front x = c s runs into the bar; behind it
  u_t = 0 and u_x = -v/c: u = -gap - v x / c, the stress E u_x = -rho c v, so the contact
  stress is lambda = rho c v;
* the front reaches the free end at s = L/c and reflects as the unloading front
  x = 2L - c s; behind it u_x = 0 (free end) and u_t = +v: u = -gap + v (s - 2L/c);
* it reaches x = 0 at s = 2L/c: the bar is unstressed and moves at +v, lambda would turn
  negative: the bar leaves the obstacle at t1 and flies away at +v (no second impact).

One formula holds at all times (before the impact and after the release included):

    u(x, t) = -gap - (v / c) min(c s, x, 2L - c s).

Every zone has the energy density 1/2 rho v^2 (1/2 E (v/c)^2 = 1/2 rho v^2 behind the first
front): the energy 1/2 rho v^2 L is constant; the momentum goes from -rho v L to +rho v L,
the impulse of the contact stress rho c v over 2L/c. On a front the zone ahead of the first
front and behind the reflected one are chosen (the contact stress is rho c v on [t0, t1)).

Doyen, Ern and Piperno's own values could not be read here; the defaults are ours,
dimensionless, so that every number reads in units of L, L/c and rho c v: L = E = rho = v = 1
(c = 1, contact stress 1, contact duration 2), gap = 0.2 (the impact at t0 = 0.2, a tenth of
the contact, as in demos/bar_problem.py), NX = 20 (h = 0.05, GetFEM's rod), dt = 2e-3 (the
rod's), T = t0 + 1.5 x 2L/c = 3.2 (the release at 2.2 and a flight after it).

The plane bar of ``demos/bar_problem.py`` (Poisson's ratio 0, so exactly this 1-D motion
along x) has the same closed form: :class:`PlaneBarExact`.
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


def _zones(x, t, L, c, t0):
    """(ahead of the compression front, behind the reflected front) at (x, t); elsewhere the
    bar is compressed and at rest."""
    cs = c * (np.asarray(t, dtype=float) - t0)
    ahead = cs < x
    behind = ~ahead & (2.0 * L - cs <= x)
    return cs, ahead, behind


def displacement(x, t, L, c, v, gap):
    """u(x, t) = -gap - (v/c) min(c s, x, 2L - c s), s = t - gap/v (x, t broadcast)."""
    cs, ahead, behind = _zones(x, t, L, c, gap / v)
    return -gap - (v / c) * np.where(ahead, cs, np.where(behind, 2.0 * L - cs, x))


def velocity(x, t, L, c, v, gap):
    """u_t(x, t): -v ahead of the compression front, +v behind the reflected one, else 0."""
    _, ahead, behind = _zones(x, t, L, c, gap / v)
    return np.where(ahead, -v, np.where(behind, v, 0.0))


def strain(x, t, L, c, v, gap):
    """u_x(x, t): -v/c in the compressed zone, else 0."""
    _, ahead, behind = _zones(x, t, L, c, gap / v)
    return np.where(ahead | behind, 0.0, -v / c)


class BarExact(ExactSolution):
    """The bar's closed form (module docstring), in the :class:`ExactSolution` interface.

    Args:
        L, E, rho, v, gap: the bar's length, Young's modulus, density, speed toward the
            obstacle and initial distance to it.
        horizon: the time up to which :attr:`contact_intervals` is listed.
    """

    def __init__(self, L, E, rho, v, gap, horizon=None):
        self.L, self.E, self.rho, self.v, self.gap = float(L), float(E), float(rho), float(v), float(gap)
        self.c = float(np.sqrt(E / rho))
        self.t0 = self.gap / self.v
        self.t1 = self.t0 + 2.0 * self.L / self.c
        #: the contact stress during the contact, rho c v
        self.stress = self.rho * self.c * self.v
        self.energy = 0.5 * self.rho * self.v ** 2 * self.L
        self.horizon = self.t1 if horizon is None else float(horizon)
        self.contact_point = np.zeros(3)

    def _args(self):
        return self.L, self.c, self.v, self.gap

    def displacement(self, x, t):
        return displacement(coordinate(x), t, *self._args())

    def velocity(self, x, t):
        return velocity(coordinate(x), t, *self._args())

    def strain(self, x, t):
        return strain(coordinate(x), t, *self._args())

    def contact_stress(self, t):
        """lambda(t) = -E u_x(0, t): rho c v on [t0, t1), else 0."""
        t = np.asarray(t, dtype=float)
        return -self.E * strain(np.zeros_like(t), t, *self._args()) + 0.0

    def intervals(self, T):
        return [(self.t0, self.t1)] if self.t0 < T else []


class PlaneBarExact(BarExact):
    """The plane bar [d, d + L] x [0, H] of ``demos/bar_problem.py`` (Poisson's ratio 0, the
    wall x = 0, initial velocity (-v, 0)): u = (u_1D(x - d, t), 0) with gap = d, the 1-D
    closed form; :meth:`strain` is the gradient (2, 2, n), zero but for du_x/dx."""
    value_shape = (2,)

    def __init__(self, L, E, rho, v, gap, H, horizon=None):
        super().__init__(L, E, rho, v, gap, horizon)
        self.contact_point = np.array([self.gap, 0.5 * H, 0.0])

    def _vector(self, values):
        return np.vstack([values, np.zeros_like(values)])

    def displacement(self, x, t):
        return self._vector(super().displacement(coordinate(x) - self.gap, t))

    def velocity(self, x, t):
        return self._vector(super().velocity(coordinate(x) - self.gap, t))

    def strain(self, x, t):
        exx = super().strain(coordinate(x) - self.gap, t)
        out = np.zeros((2, 2) + exx.shape)
        out[0, 0] = exx
        return out


def exact(problem):
    """The closed form of a ``bar`` Problem (:class:`BarExact` of its parameters)."""
    p = problem.parameters
    return BarExact(p["L"], p["E"], p["rho"], p["v"], p["gap"], horizon=SPEC.defaults["T"])


def plane_exact(problem):
    """The closed form of the plane bar of ``demos/bar_problem.py`` (:class:`PlaneBarExact`)."""
    p = problem.parameters
    if p.get("nu", 0.0) != 0.0:
        raise ValueError("the plane bar has the 1-D closed form only for Poisson's ratio 0")
    return PlaneBarExact(p["L"], p["E"], p["rho"], p["v"], p["gap"], p["H"])


def _build(comm, L, E, rho, v, gap, NX):
    """The bar Problem for declared values (see :data:`SPEC`)."""
    msh = dmesh.create_interval(comm, NX, [0.0, L])
    tol = 1e-10 * L

    def at_contact(x):
        return np.abs(x[0]) <= tol

    points = np.sort(dmesh.locate_entities_boundary(msh, 0, at_contact)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, 0, points, np.ones_like(points)))(1)
    zero = fem.Constant(msh, PETSc.ScalarType(0.0))      # no load (l must be a form)
    c = float(np.sqrt(E / rho))

    def flux(u):
        """The stress (a flux vector of the scalar u): sigma(u) = E du/dx."""
        return E * ufl.grad(u)

    return _problem.Problem(
        name="bar", mesh=msh, shape=(), rho=rho,
        a=lambda u, w: ufl.inner(flux(u), ufl.grad(w)) * ufl.dx,
        l=lambda w: zero * w * ufl.dx,
        stress=flux,
        u0=lambda x: np.zeros(x.shape[1]),
        v0=lambda x: np.full(x.shape[1], -v),
        constraint_vertices=lambda m: dmesh.locate_entities(m, 0, at_contact),
        lower_bound=lambda x: np.full(x.shape[1], -gap),      # u(0) >= -gap: the obstacle
        # the point x = 0: its measure is 1, so the stress is the nodal multiplier
        constraint_measure=lambda q: q * ds_c,
        probe=(0.0, 0.0),
        extra_columns=("contact_force", "momentum_x", "elastic"),
        parameters={"L": L, "E": E, "rho": rho, "v": v, "gap": gap, "NX": NX, "h": L / NX, "c": c,
                    "impact_time": gap / v, "contact_duration": 2.0 * L / c, "contact_stress": rho * c * v,
                    "probe": "the contact end x = 0"},
        units={"all": "dimensionless, or any consistent units (L length, E stress, rho mass/length^3, "
                      "v length/time)"},
    )


#: the bar's parameters, declared once (command line, TOML, run.json, rebuild)
PARAMS = (
    Param("L", 1.0, "length of the bar", low=0.0, low_strict=True),
    Param("E", 1.0, "Young's modulus", low=0.0, low_strict=True),
    Param("rho", 1.0, "density", low=0.0, low_strict=True),
    Param("v", 1.0, "initial speed toward the obstacle (the initial velocity is -v)", low=0.0, low_strict=True),
    Param("gap", 0.2, "initial distance from the end x = 0 to the obstacle (impact at t0 = gap / v)", low=0.0),
    Param("NX", 20, "cells of the interval mesh of [0, L], h = L/NX", type=int, low=1),
)


def estimate(values):
    """The interval mesh the parameter ``values`` make (for the memory estimate of a run)."""
    nx = values["NX"]
    return {"vertices": nx + 1, "edges": nx, "cells": nx, "value_size": 1, "by": ("NX",)}


SPEC = ProblemSpec(
    name="bar", build=_build, params=PARAMS, estimate=estimate, doc=(__doc__ or "").strip(), exact=exact,
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 2e-3, "T": 3.2, "time_unit": "dimensionless"},
)


def problem(comm: MPI.Comm = MPI.COMM_WORLD, **values: Any) -> Problem:
    """The bar; ``values`` are :data:`PARAMS` (``L``, ``E``, ``rho``, ``v``, ``gap``, ``NX``)."""
    return SPEC.problem(comm, **values)
