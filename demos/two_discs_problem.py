"""Two identical elastic discs meeting head on: contact between curved deformable bodies (a problem file).

    python -m sdm_dolfinx run --problem-file demos/two_discs_problem.py --out output/two_discs

The paper's disc (section 5: radius 20 mm, plane strain, lambda = 300, mu = 150 N/mm^2,
rho = 1e-6 t/mm^3, the gmsh mesh of ``--level``) and its mirror image in the plane y = 0, one mesh
of two connected parts: disc 1 centred at (0, R + d) moving down at v, disc 2 centred at (0, -R - d)
moving up at v, no gravity. Contact pair: the vertices of disc 1's lower half (slave) stay outside
disc 2's upper half (master), frictionless; ``--passes 2`` adds the pair ``back`` (disc 2's upper
vertices outside disc 1's lower half: the vertices of both faces held; a P2 face still sinks between its
vertices, which ``--constrain weighted`` holds on average).

By symmetry each disc behaves as the built-in disc falling at v onto the rigid foundation y = 0 from
the height d without gravity (``python -m sdm_dolfinx disc --gravity 0 --height d --v0 -v``), whose
upper disc's mesh is the same. On these mirrored meshes every slave vertex in contact meets its
mirror image: the two-body rows then are the foundation's rows doubled, and the runs differ only
where a slave vertex near the contact edge projects on a master facet rather than on its mirror
vertex (a curved surface: an O(h^2 / R) difference in the gap of the vertices about to touch),
measured in tests/physics/test_two_bodies.py.

Units: mm, N, s, tonne (stresses in MPa, energies in mJ per mm of thickness).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.compat.mesh import create_mesh, mesh_geometry_dofmap
from sdm_dolfinx.problems import ContactPair, Param, Problem, ProblemSpec, facets_where, slave_facets
from sdm_dolfinx.problems.disc import sigma
from sdm_dolfinx.problems.disc_mesh import LEVELS, make_mesh


def two_discs_mesh(comm, h, radius, d):
    """Disc 1 of radius ``radius`` centred at (0, radius + d) (the built-in disc's gmsh mesh, curved P2
    cells) and its mirror image in y = 0, one mesh partitioned by dolfinx over ``comm``."""
    if comm.rank == 0:
        one, _ = make_mesh(h, radius=radius, centre=(0.0, radius + d), comm=MPI.COMM_SELF)
        x1 = np.asarray(one.geometry.x[:, :2], dtype=float)
        cells1 = np.asarray(mesh_geometry_dofmap(one), dtype=np.int64)
        x = np.vstack([x1, x1 * np.array([1.0, -1.0])])
        cells = np.vstack([cells1, cells1 + len(x1)])
    else:
        x, cells = np.zeros((0, 2)), np.zeros((0, 6), dtype=np.int64)
    return create_mesh(comm, cells, x, ufl.Mesh(compat.element("Lagrange", "triangle", 2, (2,))))


def build(comm, level, radius, height, rho, lame_lambda, lame_mu, v, passes):
    """The two discs for declared values (see PARAMS)."""
    cy, tol = radius + height, 1e-8 * radius
    msh = two_discs_mesh(comm, LEVELS[level], radius, height)
    fdim = msh.topology.dim - 1

    def half(upper):
        """The disc near the plane of symmetry: the upper disc's lower half (``upper``) or the lower disc's
        upper half, its boundary facets chosen by their cells' side (touching discs differ)."""
        return facets_where(lambda x: np.abs(x[1]) <= cy + tol, side=lambda c: (c[1] > 0) == upper)

    pairs = [ContactPair(slave=half(True), master=half(False), name="discs")]
    if passes == 2:
        pairs.append(ContactPair(slave=half(False), master=half(True), name="back"))
    slave = slave_facets(pairs, msh)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(
        msh, fdim, slave, np.ones(len(slave), dtype=np.int32)))(1)
    zero = fem.Constant(msh, PETSc.ScalarType((0.0, 0.0)))
    return Problem(
        name="two_discs", mesh=msh, shape=(2,), rho=rho,
        a=lambda u, w: ufl.inner(sigma(u, lame_lambda, lame_mu), ufl.sym(ufl.grad(w))) * ufl.dx,
        stress=lambda u: sigma(u, lame_lambda, lame_mu),
        l=lambda w: ufl.inner(zero, w) * ufl.dx,
        u0=lambda x: np.zeros((2, x.shape[1])),
        v0=lambda x: np.vstack([np.zeros(x.shape[1]), np.where(x[1] > 0.0, -v, v)]),
        constraint_vertices=None, lower_bound=None,
        contact_pairs=pairs,
        constraint_component=1,
        constraint_measure=lambda q: q * ds_c,
        probe=(0.0, height),                                      # disc 1's lowest point
        extra_columns=("contact_force", "momentum_y", "elastic"),
        momentum_component=1,
        parameters={"level": level, "h": LEVELS[level], "radius": radius, "height": height, "rho": rho,
                    "lame_lambda": lame_lambda, "lame_mu": lame_mu, "v": v, "plane": "strain", "passes": passes,
                    "mass": 2.0 * rho * np.pi * radius ** 2},
        units={"radius": "mm", "height": "mm", "rho": "t/mm^3", "lame_lambda": "N/mm^2", "lame_mu": "N/mm^2",
               "v": "mm/s", "t": "s", "u_probe": "mm", "lambda_probe": "N/mm^2 (>= 0 compressive)",
               "contact_force": "N per mm of thickness"},
    )


PARAMS = (
    Param("level", 1, "the built-in disc's mesh level (gmsh size 4.7, 2.18, 1.07, 0.53 mm)", type=int,
          choices=(1, 2, 3, 4)),
    Param("radius", 20.0, "radius of each disc", unit="mm", low=0.0, low_strict=True),
    Param("height", 10.0, "distance of each disc's nearest point to the plane y = 0", unit="mm", low=0.0),
    Param("rho", 1e-6, "density", unit="t/mm^3", low=0.0, low_strict=True),
    Param("lame_lambda", 300.0, "Lamé's first parameter", unit="N/mm^2", low=0.0),
    Param("lame_mu", 150.0, "shear modulus", unit="N/mm^2", low=0.0, low_strict=True),
    Param("v", 1000.0, "speed of each disc toward the other", unit="mm/s", low=0.0, low_strict=True),
    Param("passes", 1, "node-to-surface passes: 1 (disc 1's lower vertices against disc 2's upper half) or 2 (and "
                       "disc 2's against disc 1's: the pair 'back')", type=int, low=1, high=2),
)

PROBLEM = ProblemSpec(
    name="two_discs", build=build, params=PARAMS, doc=__doc__,
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 1e-4, "T": 0.02, "time_unit": "s"},
)
