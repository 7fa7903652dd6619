"""The membrane over an obstacle (paper sections 3–4).

Omega = (0, 1)^2, u'' - Laplace(u) = f in Omega, u >= 0 (the obstacle), u = 0.02 on the
boundary, u(0) = 0.02, u'(0) = 0, f = -0.6; structured N x N mesh (h = 1/N).
"""
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import mesh as dmesh

from sdm_dolfinx.problems import base as _problem
from sdm_dolfinx.problems.base import Param, Problem, ProblemSpec

DIAGONALS = {"right": dmesh.DiagonalType.right, "left": dmesh.DiagonalType.left,
             "left_right": dmesh.DiagonalType.left_right, "right_left": dmesh.DiagonalType.right_left,
             "crossed": dmesh.DiagonalType.crossed}


def make_mesh(N, diagonal="right", comm=MPI.COMM_WORLD):
    """The unit square cut into N x N squares, each split into triangles (``diagonal``).

    ``left_right`` is GetFEM's ``regular simplices`` pattern used by the paper's program.
    """
    return dmesh.create_unit_square(comm, N, N, dmesh.CellType.triangle, diagonal=DIAGONALS[diagonal])


def _build(comm, N, f, u0, g, obstacle, diagonal, probe, with_obstacle):
    """The membrane Problem for declared values (see :data:`SPEC`)."""
    msh = make_mesh(N, diagonal, comm)
    tdim = msh.topology.dim

    def boundary_facets(m):
        m.topology.create_connectivity(tdim - 1, tdim)
        return dmesh.exterior_facet_indices(m.topology)

    def interior_vertices(m):
        if not with_obstacle:
            return np.zeros(0, dtype=np.int32)
        # geometric, on every local vertex: locate_entities_boundary would miss a boundary
        # vertex on a rank that holds none of its boundary facets (and call it interior)
        return dmesh.locate_entities(m, 0, lambda x: ~(np.isclose(x[0], 0) | np.isclose(x[0], 1)
                                                       | np.isclose(x[1], 0) | np.isclose(x[1], 1)))

    return _problem.Problem(
        name="membrane", mesh=msh, shape=(),
        a=lambda u, w: ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx,
        l=lambda w: f * w * ufl.dx,
        u0=lambda x: np.full(x.shape[1], u0),
        v0=lambda x: np.zeros(x.shape[1]),
        constraint_vertices=interior_vertices,
        lower_bound=lambda x: np.full(x.shape[1], obstacle),
        constraint_measure=lambda q: q * ufl.dx,
        dirichlet_facets=boundary_facets,
        dirichlet_value=lambda x: np.full(x.shape[1], g),
        probe=probe,
        parameters={"N": N, "h": 1.0 / N, "f": f, "u0": u0, "g": g, "obstacle": obstacle, "diagonal": diagonal,
                    "with_obstacle": with_obstacle},
        units={"all": "dimensionless (paper section 4)"},
    )


#: the membrane's parameters, declared once (command line, TOML, run.json, rebuild)
PARAMS = (
    Param("N", 10, "squares per side of the unit square, h = 1/N", type=int, low=1),
    Param("diagonal", "right", "triangle pattern; left_right is GetFEM's 'regular simplices' of the paper",
          type=str, choices=tuple(sorted(DIAGONALS))),
    Param("f", -0.6, "load f"),
    Param("u0", 0.02, "initial displacement"),
    Param("g", 0.02, "Dirichlet value on the boundary"),
    Param("obstacle", 0.0, "obstacle height"),
    Param("with_obstacle", True, "remove the constraint", flag="no-obstacle"),
    Param("probe", (0.5, 0.5), "probe point", metavar=("X", "Y")),
)


def _check(values, label):
    if not all(0.0 <= c <= 1.0 for c in values["probe"]):
        return [f"{label('probe')} must lie in the unit square (got {tuple(values['probe'])})"]
    return []


def estimate(values):
    """The mesh the parameter ``values`` make, counted without building it (for the memory
    estimate of a run, :func:`sdm_dolfinx.run.memory.estimate_memory`): vertices, edges and
    triangles, the components of u, and the parameters that set the size (for messages)."""
    N = values["N"]
    crossed = values["diagonal"] == "crossed"           # a centre vertex and 4 triangles per square
    vertices = (N + 1) ** 2 + (N * N if crossed else 0)
    cells = (4 if crossed else 2) * N * N
    return {"vertices": vertices, "edges": vertices + cells - 1,   # Euler: V - E + F = 1
            "cells": cells, "value_size": 1, "by": ("N", "diagonal") if crossed else ("N",)}


SPEC = ProblemSpec(
    name="membrane", build=_build, params=PARAMS, check=_check, estimate=estimate,
    doc=(__doc__ or "").strip(),
    defaults={"pair": "P1+/P0", "scheme": "midpoint", "dt": 1e-3, "T": 0.8, "time_unit": "dimensionless"},
)


def problem(comm: MPI.Comm = MPI.COMM_WORLD, **values: Any) -> Problem:
    """The paper's membrane problem; ``values`` are :data:`PARAMS` (``N``, ``f``, ``u0``, ``g``,
    ``obstacle``, ``diagonal``, ``probe``, ``with_obstacle``), the others at their defaults."""
    return SPEC.problem(comm, **values)
