"""Two elastic bars meeting end to end: contact between two deformable bodies (a problem file).

    python -m sdm_dolfinx run --problem-file demos/two_bars_problem.py --out output/two_bars
    python -m sdm_dolfinx run --problem-file demos/two_bars_problem.py --v2 1000 --out output/head_on

Two identical plane bars, [-d - L, -d] x [0, H] (the striker, bar 1, moving at +v) and its mirror
image [d, d + L] x [0, H] (bar 2, moving at -v2; at rest by default), one mesh of two connected
parts (``--Ny1``: bar 1 meshed with another number of cells across, so that the contact faces'
vertices do not match). Contact pair: the vertices of bar 1's end face x = -d (slave) stay outside bar 2's end face
x = d (master), frictionless. The gap 2 d closes at t0 = 2 d / (v + v2).

With Poisson's ratio 0 (Lamé lambda = 0, E = 2 mu) the plane motion is the 1-D one (see
demos/bar_problem.py), and the exact solution is d'Alembert's: at the impact the faces take the
common velocity (v - v2) / 2 (equal impedances rho c), a compression front of stress
rho c (v + v2) / 2 runs into each bar, reflects at its free end as an unloading front, and both
fronts reach the contact faces together at t0 + 2 L / c: the bars separate with their velocities
exchanged (bar 1 at -v2, bar 2 at +v). The contact lasts 2 L / c at the stress rho c (v + v2) / 2,
its impulse rho c (v + v2) L H = the momentum rho L H (v + v2) that each bar's velocity changes by.
Bar striking a bar at rest (v2 = 0): the striker stops, the struck bar leaves at v, the stress is
rho c v / 2 (half the stress of a bar striking a rigid wall, rho c v). Head on (v2 = v): each bar
behaves as one bar striking a rigid wall at the plane of symmetry x = 0 (demos/bar_problem.py with
the same d), at the stress rho c v.

``--passes 2``: the node-to-surface contact in both directions, a second pair ``back`` holding bar 2's
end vertices outside bar 1's end face (the two passes: the vertices of both faces held). On matching
faces (the default mesh) each row of the second pass repeats one of the first (the same two vertices,
the opposite normal): the run is the one-pass run to the solver's tolerance, the force split equally between the two pairs (docs/contact.md, "Two passes").

The time series has each bar's columns (``bodies``): ``momentum_striker_x``, ``kinetic_striker``,
``elastic_striker`` and the struck bar's, and the pair's ``contact_force_ends``.

Units: mm, N, s, tonne; defaults: steel bars, L = 100 mm, H = 10 mm, E = 200 GPa,
rho = 7850 kg/m^3, v = 1 m/s (c = 5048 m/s, 2L/c = 39.6 us, rho c v / 2 = 19.8 MPa).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.compat.mesh import create_mesh, mesh_geometry_dofmap
from sdm_dolfinx.problems import (Body, ContactPair, Param, Problem, ProblemSpec, cells_where, facets_where,
                                  slave_facets)


def _rectangle(d, L, H, Nx, Ny):
    """(points (n, 2), triangles (m, 3)) of ``create_rectangle``'s mesh of [d, d + L] x [0, H]."""
    one = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([d, 0.0]), np.array([d + L, H])], [Nx, Ny],
                                 dmesh.CellType.triangle)
    return np.asarray(one.geometry.x[:, :2], dtype=float), np.asarray(mesh_geometry_dofmap(one), dtype=np.int64)


def two_bars_mesh(comm, L, H, d, Nx, Ny, Ny1=None):
    """The mesh of bar 2, [d, d + L] x [0, H] (``create_rectangle``'s triangles), and bar 1 on its left:
    bar 2's mirror image (x -> -x), or with ``Ny1`` cells across it (non-matching contact faces), one mesh
    partitioned by dolfinx over ``comm``."""
    if comm.rank == 0:
        x2, cells2 = _rectangle(d, L, H, Nx, Ny)
        x1, cells1 = (x2 * np.array([-1.0, 1.0]), cells2) if Ny1 in (None, Ny) else _rectangle(-d - L, L, H, Nx, Ny1)
        x = np.vstack([x2, x1])
        cells = np.vstack([cells2, cells1 + len(x2)])
    else:
        x, cells = np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    domain = ufl.Mesh(compat.element("Lagrange", "triangle", 1, (2,)))
    return create_mesh(comm, cells, x, domain)


def build(comm, L, H, E, rho, v, v2, Nx, Ny, Ny1, gap_time, passes):
    """The two bars for declared values (see PARAMS)."""
    c = np.sqrt(E / rho)
    t0 = 0.1 * 2.0 * L / c if gap_time is None else gap_time
    d = 0.5 * (v + v2) * t0                 # each end face at distance d from x = 0
    msh = two_bars_mesh(comm, L, H, d, Nx, Ny, Ny1)
    fdim = msh.topology.dim - 1

    def facets(x0, side):
        """The end face x = x0 of the bar on the ``side`` (-1, +1) of x = 0 (by its cells, so that touching
        faces differ)."""
        return facets_where(lambda x: np.isclose(x[0], x0, rtol=0.0, atol=1e-9 * L), side=lambda c: side * c[0] > 0)

    def side_cells(side):
        """The cells of the bar on the ``side`` (-1, +1) of x = 0."""
        return cells_where(lambda c: side * c[0] > 0)

    pairs = [ContactPair(slave=facets(-d, -1), master=facets(d, 1), name="ends")]
    if passes == 2:
        pairs.append(ContactPair(slave=facets(d, 1), master=facets(-d, -1), name="back"))
    slave = slave_facets(pairs, msh)
    tags = dmesh.meshtags(msh, fdim, slave, np.full(len(slave), 1, dtype=np.int32))
    ds_slave = ufl.Measure("ds", domain=msh, subdomain_data=tags)(1)     # every pair's slave facets
    zero = fem.Constant(msh, PETSc.ScalarType((0.0, 0.0)))
    lame_mu = E / 2.0

    def velocity(x):
        return np.vstack([np.where(x[0] < 0.0, v, -v2), np.zeros(x.shape[1])])

    return Problem(
        name="two_bars", mesh=msh, shape=(2,), rho=rho,
        a=lambda u, w: ufl.inner(2.0 * lame_mu * ufl.sym(ufl.grad(u)), ufl.sym(ufl.grad(w))) * ufl.dx,
        l=lambda w: ufl.inner(zero, w) * ufl.dx,
        u0=lambda x: np.zeros((2, x.shape[1])),
        v0=velocity,
        constraint_vertices=None, lower_bound=None,
        contact_pairs=pairs,
        constraint_component=0,
        constraint_measure=lambda q: q * ds_slave,
        probe=(-d, H / 2.0),                                       # the middle of the striker's end face
        extra_columns=("contact_force", "momentum_x", "elastic"),
        bodies=[Body("striker", side_cells(-1)), Body("struck", side_cells(1))],
        momentum_component=0,
        parameters={"L": L, "H": H, "E": E, "nu": 0.0, "rho": rho, "v": v, "v2": v2, "gap": 2.0 * d,
                    "gap_time": t0, "passes": passes, "Nx": Nx, "Ny": Ny, "Ny1": Ny if Ny1 is None else Ny1, "c": c,
                    "lame_lambda": 0.0, "lame_mu": lame_mu},
        units={"L": "mm", "H": "mm", "E": "N/mm^2", "rho": "t/mm^3", "v": "mm/s", "v2": "mm/s", "gap": "mm",
               "t": "s", "u_probe": "mm", "lambda_probe": "N/mm^2 (>= 0 compressive)",
               "contact_force": "N per mm of thickness", "lame_lambda": "N/mm^2", "lame_mu": "N/mm^2"},
    )


PARAMS = (
    Param("L", 100.0, "length of each bar", unit="mm", low=0.0, low_strict=True),
    Param("H", 10.0, "height of each bar", unit="mm", low=0.0, low_strict=True),
    Param("E", 2.0e5, "Young's modulus (Poisson's ratio 0)", unit="N/mm^2", low=0.0, low_strict=True),
    Param("rho", 7.85e-9, "density", unit="t/mm^3", low=0.0, low_strict=True),
    Param("v", 1000.0, "speed of bar 1 (the striker) toward bar 2", unit="mm/s", low=0.0, low_strict=True),
    Param("v2", 0.0, "speed of bar 2 toward bar 1 (0: at rest; v: head on)", unit="mm/s", low=0.0),
    Param("Nx", 40, "cells along each bar (each split into two triangles)", type=int, low=1),
    Param("Ny", 4, "cells across each bar", type=int, low=1),
    Param("Ny1", None, "cells across bar 1, the striker (default: Ny, bar 2's mirror image; another value: "
                       "non-matching contact faces)", type=int, low=1),
    Param("passes", 1, "node-to-surface passes: 1 (bar 1's end vertices against bar 2's face) or 2 (and bar 2's "
                       "against bar 1's)", type=int, low=1, high=2),
    Param("gap_time", None, "time at which the end faces meet (default: a tenth of 2L/c)", unit="s",
          type=float, low=0.0),
)

PROBLEM = ProblemSpec(
    name="two_bars", build=build, params=PARAMS, doc=__doc__,
    # dt = h / (2c) and T = t0 + 1.5 x 2L/c for the defaults (Nx = 40)
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 2.5e-7, "T": 6.5e-5, "time_unit": "s"},
)
