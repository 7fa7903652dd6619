"""Newton's cradle of elastic discs: several bodies and contact pairs in a row (a problem file).

    python -m sdm_dolfinx run --problem-file demos/cradle_problem.py --out output/cradle

``--n`` identical discs (the paper's disc: R = 20 mm, plane strain, lambda = 300, mu = 150 N/mm^2,
rho = 1e-6 t/mm^3, the gmsh mesh of ``--level``) in a row along x, each touching the next at a point
(centres 2R apart, no gravity); disc 1 moves at v toward the others, which are at rest. Contact pairs
``c1``, ``c2``, ...: the right half of disc k (slave) stays outside the left half of disc k + 1
(master), frictionless; disc k is master of pair k - 1 and slave of pair k. Bodies ``disc1``, ...: each
disc's momentum, kinetic and elastic energy (per-body columns).

Rigid discs with perfectly elastic, instantaneous contacts hand the momentum on unchanged: the
velocities (1, 0, ..., 0) v become (0, ..., 0, 1) v. Elastic discs keep part of the energy as vibration
and the contacts overlap in time, so the first discs keep small velocities, the last leaves a little
slower (the elastic-wave correction, measured in tests/physics/test_two_bodies.py); the total momentum
stays n m v / n = m v exactly and the energy is conserved by the midpoint scheme up to its contact
steps.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.compat.mesh import create_mesh, mesh_geometry_dofmap
from sdm_dolfinx.problems import Body, ContactPair, Param, Problem, ProblemSpec, cells_where, facets_where
from sdm_dolfinx.problems.disc import sigma
from sdm_dolfinx.problems.disc_mesh import LEVELS, make_mesh


def cradle_mesh(comm, n, h, radius):
    """``n`` copies of the disc mesh of ``radius`` centred at (2 k radius, 0), k = 0..n-1 (touching at
    their equator points, which gmsh puts exactly there), one mesh partitioned by dolfinx over ``comm``."""
    if comm.rank == 0:
        one, _ = make_mesh(h, radius=radius, centre=(0.0, 0.0), comm=MPI.COMM_SELF)
        x1 = np.asarray(one.geometry.x[:, :2], dtype=float)
        cells1 = np.asarray(mesh_geometry_dofmap(one), dtype=np.int64)
        x = np.vstack([x1 + np.array([2.0 * k * radius, 0.0]) for k in range(n)])
        cells = np.vstack([cells1 + k * len(x1) for k in range(n)])
    else:
        x, cells = np.zeros((0, 2)), np.zeros((0, 6), dtype=np.int64)
    return create_mesh(comm, cells, x, ufl.Mesh(compat.element("Lagrange", "triangle", 2, (2,))))


def build(comm, n, level, radius, rho, lame_lambda, lame_mu, v):
    """The cradle for declared values (see PARAMS)."""
    msh = cradle_mesh(comm, n, LEVELS[level], radius)
    tdim = msh.topology.dim
    fdim, tol = tdim - 1, 1e-8 * radius

    def of_disc(k):
        """Whether points (cells' midpoints) are in disc k (0..n-1)."""
        return lambda c: np.rint(c[0] / (2.0 * radius)) == k

    def half(k, right):
        """Disc k's boundary facets on its right (``right``) or left half."""
        centre = 2.0 * k * radius
        return facets_where((lambda x: x[0] >= centre - tol) if right else (lambda x: x[0] <= centre + tol),
                            side=of_disc(k))

    def cells_of(k):
        return cells_where(of_disc(k))

    slaves = np.sort(np.concatenate([half(k, True)(msh) for k in range(n - 1)])).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(
        msh, fdim, slaves, np.ones(len(slaves), dtype=np.int32)))(1)
    zero = fem.Constant(msh, PETSc.ScalarType((0.0, 0.0)))
    return Problem(
        name="cradle", mesh=msh, shape=(2,), rho=rho,
        a=lambda u, w: ufl.inner(sigma(u, lame_lambda, lame_mu), ufl.sym(ufl.grad(w))) * ufl.dx,
        stress=lambda u: sigma(u, lame_lambda, lame_mu),
        l=lambda w: ufl.inner(zero, w) * ufl.dx,
        u0=lambda x: np.zeros((2, x.shape[1])),
        v0=lambda x: np.vstack([np.where(x[0] < radius, v, 0.0), np.zeros(x.shape[1])]),
        constraint_vertices=None, lower_bound=None,
        contact_pairs=[ContactPair(slave=half(k, True), master=half(k + 1, False), name=f"c{k + 1}")
                       for k in range(n - 1)],
        bodies=[Body(f"disc{k + 1}", cells_of(k)) for k in range(n)],
        constraint_component=0,
        constraint_measure=lambda q: q * ds_c,
        probe=(radius, 0.0),                                      # where disc 1 touches disc 2
        extra_columns=("contact_force", "momentum_x", "elastic"),
        momentum_component=0,
        parameters={"n": n, "level": level, "h": LEVELS[level], "radius": radius, "rho": rho,
                    "lame_lambda": lame_lambda, "lame_mu": lame_mu, "v": v, "plane": "strain",
                    "mass": rho * np.pi * radius ** 2},
        units={"radius": "mm", "rho": "t/mm^3", "lame_lambda": "N/mm^2", "lame_mu": "N/mm^2", "v": "mm/s",
               "t": "s", "u_probe": "mm", "lambda_probe": "N/mm^2 (>= 0 compressive)",
               "contact_force": "N per mm of thickness"},
    )


PARAMS = (
    Param("n", 3, "number of discs", type=int, low=2),
    Param("level", 1, "the built-in disc's mesh level (gmsh size 4.7, 2.18, 1.07, 0.53 mm)", type=int,
          choices=(1, 2, 3, 4)),
    Param("radius", 20.0, "radius of each disc", unit="mm", low=0.0, low_strict=True),
    Param("rho", 1e-6, "density", unit="t/mm^3", low=0.0, low_strict=True),
    Param("lame_lambda", 300.0, "Lamé's first parameter", unit="N/mm^2", low=0.0),
    Param("lame_mu", 150.0, "shear modulus", unit="N/mm^2", low=0.0, low_strict=True),
    Param("v", 1000.0, "speed of disc 1 toward the others", unit="mm/s", low=0.0, low_strict=True),
)

PROBLEM = ProblemSpec(
    name="cradle", build=build, params=PARAMS, doc=__doc__,
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 1e-4, "T": 0.03, "time_unit": "s"},
)
