"""Two identical elastic balls meeting head on: contact between two deformable 3-D bodies (a problem file).

    python -m sdm_dolfinx run --problem-file demos/two_balls_problem.py --out output/two_balls

The built-in ball (R = 20 mm, E = 10 N/mm^2, nu = 0.3, rho = 1000 kg/m^3, the gmsh mesh of ``--level``
refined toward its south pole) centred at (0, 0, R + d) moving down at v, and its mirror image in the
plane z = 0 moving up at v, one mesh of two connected parts, no gravity. Contact pair: the vertices of
ball 1's lower hemisphere (slave) stay outside ball 2's upper hemisphere (master), frictionless.

Hertz: two equal spheres at +-v have the reduced radius R/2, the reduced modulus E*/2 and the reduced
mass m/2, and approach each other at 2v; their mutual approach is twice the single ball's on a rigid
plane at v, and the force and the contact time are the single ball's: F_max = 3.161 N and
t_c = 3.896 ms at the defaults (:func:`sdm_dolfinx.problems.ball.hertz`). By symmetry each ball is the
built-in ball on its plane (``python -m sdm_dolfinx ball --height d``), whose mesh is ball 1's.

Units: mm, N, s, tonne (stresses in MPa, energies in mJ, momenta in N s).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.compat.mesh import create_mesh, mesh_geometry_dofmap
from sdm_dolfinx.problems import ContactPair, Param, Problem, ProblemSpec
from sdm_dolfinx.problems import ball, ball_mesh


def two_balls_mesh(comm, level, radius, height, a):
    """Ball 1 of ``radius`` centred at (0, 0, radius + height) (the built-in ball's gmsh mesh at ``level``,
    curved P2 tetrahedra) and its mirror image in z = 0, one mesh partitioned by dolfinx over ``comm``."""
    if comm.rank == 0:
        hf, hc = ball.mesh_sizes(level, None, None, radius, a)
        one, _ = ball_mesh.make_mesh(hf, hc, a, radius, (0.0, 0.0, radius + height), comm=MPI.COMM_SELF)
        x1 = np.asarray(one.geometry.x, dtype=float)
        cells1 = np.asarray(mesh_geometry_dofmap(one), dtype=np.int64)
        x = np.vstack([x1, x1 * np.array([1.0, 1.0, -1.0])])
        cells = np.vstack([cells1, cells1 + len(x1)])
    else:
        x, cells = np.zeros((0, 3)), np.zeros((0, 10), dtype=np.int64)
    return create_mesh(comm, cells, x, ufl.Mesh(compat.element("Lagrange", "tetrahedron", 2, (3,))))


def build(comm, level, radius, height, E, nu, rho, v):
    """The two balls for declared values (see PARAMS)."""
    ref = ball.hertz(radius, E, nu, rho, v)
    cy, tol = radius + height, 1e-8 * radius
    msh = two_balls_mesh(comm, level, radius, height, ref["a"])
    fdim = msh.topology.dim - 1
    lmbda, mu = ball.lame(E, nu)

    def half(upper):
        """The ball near the plane of symmetry: the upper ball's lower half (``upper``) or the lower ball's
        upper half, its boundary facets chosen by their cells' side (touching balls differ)."""
        def found(m):
            m.topology.create_connectivity(fdim, fdim + 1)
            f = dmesh.locate_entities_boundary(m, fdim, lambda x: np.abs(x[2]) <= cy + tol)
            f2c = m.topology.connectivity(fdim, fdim + 1)
            mid = dmesh.compute_midpoints(m, fdim + 1, f2c.array[f2c.offsets[f]])[:, 2] if len(f) else np.zeros(0)
            return f[(mid > 0) == upper]
        return found

    slave = np.sort(half(True)(msh)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(
        msh, fdim, slave, np.ones(len(slave), dtype=np.int32)))(1)
    zero = fem.Constant(msh, PETSc.ScalarType((0.0, 0.0, 0.0)))
    return Problem(
        name="two_balls", mesh=msh, shape=(3,), rho=rho,
        a=lambda u, w: ufl.inner(ball.sigma(u, lmbda, mu), ufl.sym(ufl.grad(w))) * ufl.dx,
        stress=lambda u: ball.sigma(u, lmbda, mu),
        l=lambda w: ufl.inner(zero, w) * ufl.dx,
        u0=lambda x: np.zeros((3, x.shape[1])),
        v0=lambda x: np.vstack([0.0 * x[0], 0.0 * x[0], np.where(x[2] > 0.0, -v, v)]),
        constraint_vertices=None, lower_bound=None,
        contact_pairs=[ContactPair(slave=half(True), master=half(False), name="balls")],
        constraint_component=2,
        constraint_measure=lambda q: q * ds_c,
        probe=(0.0, 0.0, height),                                 # ball 1's south pole
        extra_columns=("contact_force", "momentum_y", "elastic"),
        momentum_component=2,
        parameters={"level": level, "radius": radius, "height": height, "E": E, "nu": nu, "rho": rho, "v": v,
                    "lame_lambda": lmbda, "lame_mu": mu, "mass": 2.0 * rho * 4.0 / 3.0 * np.pi * radius ** 3,
                    "hertz": ref},
        units={"radius": "mm", "height": "mm", "E": "N/mm^2", "rho": "t/mm^3", "v": "mm/s", "t": "s",
               "u_probe": "mm", "lambda_probe": "N/mm^2 (>= 0 compressive)", "contact_force": "N",
               "momentum_y": "N s (along z)"},
    )


PARAMS = (
    Param("level", 1, "the built-in ball's mesh level (1-5)", type=int, choices=tuple(sorted(ball_mesh.LEVELS))),
    Param("radius", 20.0, "radius of each ball", unit="mm", low=0.0, low_strict=True),
    Param("height", 0.01, "distance of each ball's nearest point to the plane z = 0", unit="mm", low=0.0),
    Param("E", 10.0, "Young's modulus", unit="N/mm^2", low=0.0, low_strict=True),
    Param("nu", 0.3, "Poisson's ratio", low=0.0, high=0.49),
    Param("rho", 1e-9, "density", unit="t/mm^3", low=0.0, low_strict=True),
    Param("v", 100.0, "speed of each ball toward the other", unit="mm/s", low=0.0, low_strict=True),
)

PROBLEM = ProblemSpec(
    name="two_balls", build=build, params=PARAMS, doc=__doc__,
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 4e-5, "T": 5e-3, "time_unit": "s"},
)
