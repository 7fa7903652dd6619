"""The Problem: everything that distinguishes one constrained hyperbolic problem from another.

A Problem is data (a mesh, UFL forms, Dirichlet data, the constrained vertices and their
bounds, initial conditions, a probe point). Nothing downstream knows which problem runs:
the membrane of the paper's section 4 and the disc of section 5 are two Problems, and a
user-defined problem is a third (see ``demos/custom_problem.py``).
"""
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np


@dataclass
class Problem:
    """A problem  M u'' + A u ∈ L − N_K(u)  in the sense of the paper's eq. (1)–(2).

    Attributes:
        name: short name, used in file names and ``run.json``.
        mesh: a dolfinx mesh (already distributed).
        shape: value shape of u: ``()`` for a scalar field, ``(gdim,)`` for a vector field.
        a: ``a(u, w)`` -> UFL bilinear form (the operator A).
        l: ``l(w)`` -> UFL linear form (the load L, gravity included).
        rho: density: the mass forms are ``rho * u.w dx``.
        u0: initial displacement, a callable ``x -> values`` for ``Function.interpolate``.
        v0: initial velocity, same form.
        constraint_vertices: ``mesh -> local vertex indices`` where K^h acts (eq. (13)).
        lower_bound: ``x (3, n) -> (n,)`` the bound on the constrained displacement
            component at vertices of coordinates x: u_c(a_i) >= lower_bound(a_i).
        constraint_component: component of u that is bounded (None for scalar u).
        constraint_measure: ``q -> UFL form`` of the P1 test function q; its value at a
            vertex is that vertex's lumped measure, so stress = nodal multiplier / measure.
        dirichlet_facets: ``mesh -> local facet indices`` with u = dirichlet_value, or None.
        dirichlet_value: callable ``x -> values`` (constant in time).
        probe: the point (x, y) where the displacement (and, at the nearest constrained
            vertex, the contact stress) is recorded.
        extra_columns: additional time-series columns among ``contact_force``,
            ``momentum_y``, ``elastic`` (1/2 U^T A U).
        parameters: physical parameters for ``run.json``; ``units`` their units.
        gravity_direction: for ``momentum_y``: the component index used.
    """
    name: str
    mesh: object
    shape: tuple
    a: Callable
    l: Callable
    u0: Callable
    v0: Callable
    constraint_vertices: Callable
    lower_bound: Callable
    constraint_measure: Callable
    rho: float = 1.0
    constraint_component: Optional[int] = None
    dirichlet_facets: Optional[Callable] = None
    dirichlet_value: Optional[Callable] = None
    probe: tuple = (0.0, 0.0)
    extra_columns: tuple = ()
    parameters: dict = field(default_factory=dict)
    units: dict = field(default_factory=dict)
    momentum_component: int = 1

    def describe(self):
        """Parameters with their units, as written to ``run.json``."""
        return {"name": self.name, "parameters": dict(self.parameters), "units": dict(self.units),
                "probe": [float(c) for c in np.asarray(self.probe)]}
