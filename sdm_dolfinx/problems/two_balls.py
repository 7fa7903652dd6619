"""Two elastic balls colliding (head on, unequal or oblique): contact between two deformable 3-D bodies.

    python -m sdm_dolfinx two_balls --out output/two_balls
    python -m sdm_dolfinx two_balls --R2 10 --E2 40 --rho2 3e-9 --v2 0 --out output/unequal
    python -m sdm_dolfinx two_balls --vt 300 --friction coulomb --mu 0.1 --out output/oblique

Ball 1: the built-in ball (R = 20 mm, E = 10 N/mm^2, nu = 0.3, rho = 1000 kg/m^3, the gmsh mesh of
``--level`` refined toward its south pole) centred at (0, 0, R + d) moving down at v. Ball 2: its mirror
image in the plane z = 0 moving up at v (by default), or a ball of its own (--R2, --E2, --nu2, --rho2,
--v2: its own mesh, refined toward its north pole), one mesh of two connected parts with the
materials and densities per cell (DG0), no gravity. Contact pair: the vertices of ball 1's lower
hemisphere (slave) stay outside ball 2's upper hemisphere (master), frictionless or (``--friction``)
with friction on their relative slip; ``--vt`` gives ball 1 a velocity across the line of centres.
``--passes 2`` adds the pair ``back`` (ball 2's upper vertices outside ball 1's lower hemisphere: on
unequal meshes the vertices of both faces held; a P2 face still sinks between its vertices, which
``--constrain weighted`` holds on average).

Hertz for two elastic spheres (:func:`hertz_two`): the curvatures add, 1/R* = 1/R1 + 1/R2, the
compliances add, 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2, the masses combine into the reduced mass
m* = m1 m2 / (m1 + m2), and the approach speed is v1 + v2: the one-sphere formulas of
:func:`sdm_dolfinx.problems.ball.hertz` with these (derivation there). Two equal spheres at +-v
approach twice as much as the single ball on a rigid plane at v, with the same force and contact
time: F_max = 3.161 N and t_c = 3.896 ms at the defaults; by symmetry each ball is then the
built-in ball on its plane (``python -m sdm_dolfinx ball --height d``), whose mesh is ball 1's.

The time series has each ball's momentum, kinetic and elastic energy (``momentum_ball1_z``, ...,
``kinetic_ball2``, ``elastic_ball2``) and the pair's ``contact_force_balls``.

Units: mm, N, s, tonne (stresses in MPa, energies in mJ, momenta in N s).
"""
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.compat.mesh import create_mesh, mesh_geometry_dofmap
from sdm_dolfinx.problems import ball, ball_mesh
from sdm_dolfinx.problems.base import Body, ContactPair, Param, Problem, ProblemSpec
from sdm_dolfinx.problems.selectors import cells_where, facets_where
from sdm_dolfinx.problems.contact_pairs import slave_facets


def hertz_two(R1, E1, nu1, rho1, v1, R2, E2, nu2, rho2, v2):
    """Hertz's impact of two elastic spheres approaching at v1 + v2 (see the module): ``ball.hertz`` of the
    reduced radius, modulus and mass (its ``E_star`` and ``mass`` are the reduced ones, ``a`` the contact
    radius, ``t_c`` the contact time)."""
    E_star = 1.0 / ((1.0 - nu1 ** 2) / E1 + (1.0 - nu2 ** 2) / E2)
    m1, m2 = (rho * 4.0 / 3.0 * np.pi * R ** 3 for rho, R in ((rho1, R1), (rho2, R2)))
    # ball.hertz takes E and nu: E = E_star with nu = 0 gives its E* = E_star
    return ball.hertz(1.0 / (1.0 / R1 + 1.0 / R2), E_star, 0.0, None, v1 + v2, mass=m1 * m2 / (m1 + m2))


def _ball_points(level, radius, height, a):
    """(points, cells) of the built-in ball's mesh of ``radius`` centred at (0, 0, radius + height)."""
    hf, hc = ball.mesh_sizes(level, None, None, radius, a)
    one, _ = ball_mesh.make_mesh(hf, hc, a, radius, (0.0, 0.0, radius + height), comm=MPI.COMM_SELF)
    return np.asarray(one.geometry.x, dtype=float), np.asarray(mesh_geometry_dofmap(one), dtype=np.int64)


def two_balls_mesh(comm, level, radius, height, a, radius2=None):
    """Ball 1 of ``radius`` centred at (0, 0, radius + height) (the built-in ball's gmsh mesh at ``level``,
    curved P2 tetrahedra) and, below the plane z = 0, its mirror image or (``radius2``) the mirror image of
    a ball of that radius: one mesh partitioned by dolfinx over ``comm``."""
    if comm.rank == 0:
        x1, cells1 = _ball_points(level, radius, height, a)
        x2, cells2 = (x1, cells1) if radius2 in (None, radius) else _ball_points(level, radius2, height, a)
        x = np.vstack([x1, x2 * np.array([1.0, 1.0, -1.0])])
        cells = np.vstack([cells1, cells2 + len(x1)])
    else:
        x, cells = np.zeros((0, 3)), np.zeros((0, 10), dtype=np.int64)
    return create_mesh(comm, cells, x, ufl.Mesh(compat.element("Lagrange", "tetrahedron", 2, (3,))))


def _per_ball(msh, upper, lower):
    """A DG0 Function equal to ``upper`` on ball 1's cells (z > 0) and ``lower`` on ball 2's."""
    f = fem.Function(compat.function_space(msh, compat.element("DG", "tetrahedron", 0)))
    cells = np.arange(msh.topology.index_map(3).size_local + msh.topology.index_map(3).num_ghosts, dtype=np.int32)
    f.x.array[:] = np.where(dmesh.compute_midpoints(msh, 3, cells)[:, 2] > 0.0, upper, lower)
    return f


def build(comm, level, radius, height, E, nu, rho, v, R2, E2, nu2, rho2, v2, vt, passes):
    """The two balls for declared values (see PARAMS)."""
    R2, E2, nu2, rho2, v2 = (radius if R2 is None else R2, E if E2 is None else E2, nu if nu2 is None else nu2,
                             rho if rho2 is None else rho2, v if v2 is None else v2)
    ref = hertz_two(radius, E, nu, rho, v, R2, E2, nu2, rho2, v2)
    cy, tol = max(radius, R2) + height, 1e-8 * radius
    msh = two_balls_mesh(comm, level, radius, height, ref["a"], R2)
    fdim = msh.topology.dim - 1
    (l1, m1), (l2, m2) = ball.lame(E, nu), ball.lame(E2, nu2)
    lmbda, mu = _per_ball(msh, l1, l2), _per_ball(msh, m1, m2)
    density = rho if rho2 == rho else _per_ball(msh, rho, rho2)

    def half(upper):
        """The ball near the plane of symmetry: the upper ball's lower half (``upper``) or the lower ball's
        upper half, its boundary facets chosen by their cells' side (touching balls differ)."""
        return facets_where(lambda x: np.where(x[2] > 0.0, x[2] <= radius + height + tol, x[2] >= -R2 - height - tol),
                            side=lambda c: (c[2] > 0) == upper)

    def side_cells(upper):
        return cells_where(lambda c: (c[2] > 0.0) == upper)

    pairs = [ContactPair(slave=half(True), master=half(False), name="balls")]
    if passes == 2:
        pairs.append(ContactPair(slave=half(False), master=half(True), name="back"))
    slave = slave_facets(pairs, msh)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(
        msh, fdim, slave, np.ones(len(slave), dtype=np.int32)))(1)
    zero = fem.Constant(msh, PETSc.ScalarType((0.0, 0.0, 0.0)))
    return Problem(
        name="two_balls", mesh=msh, shape=(3,), rho=density,
        a=lambda u, w: ufl.inner(ball.sigma(u, lmbda, mu), ufl.sym(ufl.grad(w))) * ufl.dx,
        stress=lambda u: ball.sigma(u, lmbda, mu),
        l=lambda w: ufl.inner(zero, w) * ufl.dx,
        u0=lambda x: np.zeros((3, x.shape[1])),
        v0=lambda x: np.vstack([np.where(x[2] > 0.0, vt, 0.0), 0.0 * x[0], np.where(x[2] > 0.0, -v, v2)]),
        constraint_vertices=None, lower_bound=None,
        contact_pairs=pairs,
        bodies=[Body("ball1", side_cells(True)), Body("ball2", side_cells(False))],
        constraint_component=2,
        constraint_measure=lambda q: q * ds_c,
        probe=(0.0, 0.0, height),                                 # ball 1's south pole
        extra_columns=("contact_force", "momentum_y", "elastic"),
        momentum_component=2,
        parameters={"level": level, "radius": radius, "height": height, "E": E, "nu": nu, "rho": rho, "v": v,
                    "R2": R2, "E2": E2, "nu2": nu2, "rho2": rho2, "v2": v2, "vt": vt, "passes": passes,
                    "mass1": rho * 4.0 / 3.0 * np.pi * radius ** 3, "mass2": rho2 * 4.0 / 3.0 * np.pi * R2 ** 3,
                    "hertz": ref},
        units={"radius": "mm", "height": "mm", "E": "N/mm^2", "rho": "t/mm^3", "v": "mm/s", "R2": "mm",
               "E2": "N/mm^2", "rho2": "t/mm^3", "v2": "mm/s", "vt": "mm/s", "t": "s", "u_probe": "mm",
               "lambda_probe": "N/mm^2 (>= 0 compressive)", "contact_force": "N", "momentum_y": "N s (along z)"},
    )


PARAMS = (
    Param("level", 1, "the built-in ball's mesh level (1-5)", type=int, choices=tuple(sorted(ball_mesh.LEVELS))),
    Param("radius", 20.0, "radius of ball 1", unit="mm", low=0.0, low_strict=True),
    Param("height", 0.01, "distance of each ball's nearest point to the plane z = 0", unit="mm", low=0.0),
    Param("E", 10.0, "Young's modulus of ball 1", unit="N/mm^2", low=0.0, low_strict=True),
    Param("nu", 0.3, "Poisson's ratio of ball 1", low=0.0, high=0.49),
    Param("rho", 1e-9, "density of ball 1", unit="t/mm^3", low=0.0, low_strict=True),
    Param("v", 100.0, "speed of ball 1 toward ball 2", unit="mm/s", low=0.0, low_strict=True),
    Param("R2", None, "radius of ball 2 (default: ball 1's, its mirror image)", unit="mm", type=float, low=0.0,
          low_strict=True),
    Param("E2", None, "Young's modulus of ball 2 (default: ball 1's)", unit="N/mm^2", type=float, low=0.0,
          low_strict=True),
    Param("nu2", None, "Poisson's ratio of ball 2 (default: ball 1's)", type=float, low=0.0, high=0.49),
    Param("rho2", None, "density of ball 2 (default: ball 1's)", unit="t/mm^3", type=float, low=0.0,
          low_strict=True),
    Param("v2", None, "speed of ball 2 toward ball 1 (default: ball 1's v)", unit="mm/s", type=float, low=0.0),
    Param("vt", 0.0, "ball 1's velocity along x, across the line of centres (an oblique collision: with "
                     "--friction coulomb --mu the balls exchange a tangential impulse)", unit="mm/s"),
    Param("passes", 1, "node-to-surface passes: 1 (ball 1's lower vertices against ball 2's upper half) or 2 (and "
                       "ball 2's against ball 1's: the pair 'back')", type=int, low=1, high=2),
)

SPEC = ProblemSpec(
    name="two_balls", build=build, params=PARAMS, doc=(__doc__ or "").strip(),
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 4e-5, "T": 5e-3, "time_unit": "s"},
)


def problem(comm: MPI.Comm = MPI.COMM_WORLD, **values: Any) -> Problem:
    """The two balls; ``values`` are :data:`PARAMS`, the others at their defaults."""
    return SPEC.problem(comm, **values)
