"""A block sliding on an elastic base: friction between two deformable bodies (a problem file).

    python -m sdm_dolfinx run --problem-file demos/sliding_blocks_problem.py --friction coulomb --mu 0.3 \\
        --out output/sliding_blocks

The slider [x0, x0 + width] x [gap, gap + height] (plane strain, moving at (v0, 0), its own mesh)
falls unstressed on the base [0, base_width] x [-base_height, 0] (clamped along its bottom y = -base_height),
one mesh of two connected parts; gravity g acts on both. Contact pair: the slider's bottom vertices
(slave) stay above the base's top face (master); friction (``--friction coulomb --mu``, or
``tresca``) acts on the slave vertices' slip relative to the base, the relative tangential motion.
Poisson's ratio 0 by default (as for the built-in block: a slip that moves the faces normally
excites a vertical vibration).

Closed forms. Rigid slider on a rigid base: it decelerates at mu g and stops at t* = v0 / (mu g)
(34.0 ms at the defaults with mu = 0.3, after v0^2 / (2 mu g) = 1.70 mm). For the elastic bodies an
identity holds exactly while every slave vertex in contact slips backwards: the base's top is flat
(its normal is e_y wherever the slider's vertices project, away from the base's corners), so the
friction force on the slider is -mu times the normal force N(t) >= 0, and the slider's momentum
balance gives

    p_x(t) - p_x(0) = -mu int_0^t N,     p_y(t) - p_y(0) = int_0^t N - m g t

(m = rho width height per mm of thickness), i.e. the friction impulse is mu times the normal impulse,
whatever the vertical vibration of the slider dropped on the base: p_x(t) - p_x(0) = -mu (p_y(t) -
p_y(0) + m g t) (tests/physics/test_two_body_friction.py).

The time series has each body's columns (``momentum_slider_x``, ``momentum_slider_y``, ...,
``kinetic_base``, ``elastic_base``), the pair's ``contact_force_bottom`` and the frictional columns
(``tangential_force``: the friction force on the slider along t = (n_y, -n_x) = +x, the base's normal
being +y; ``slip_probe``, ``dissipated``, ``n_stick``, ``n_slip``).

The slider keeps rattling on the base: dropped from 1 um, it leaves the base again and again (out of
contact in 22 % of the steps over 40 ms at mu = 0.3, at any dt: nothing in the linear elastic model
damps its vertical vibration), so its mean deceleration differs from mu g by up to ~10 %; the identity
above holds whatever the rattling.

Units: mm, N, s, tonne (the built-in block's: E = 1000 N/mm^2, rho = 1e-6 t/mm^3).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.compat.mesh import create_mesh, mesh_geometry_dofmap
from sdm_dolfinx.problems import Body, ContactPair, Param, Problem, ProblemSpec, cells_where, facets_where


def _rectangle(x0, x1, n):
    """(points, triangles) of ``create_rectangle``'s mesh of the box [x0, x1] with n squares."""
    one = dmesh.create_rectangle(MPI.COMM_SELF, [np.array(x0, dtype=float), np.array(x1, dtype=float)], n,
                                 dmesh.CellType.triangle)
    return np.asarray(one.geometry.x[:, :2], dtype=float), np.asarray(mesh_geometry_dofmap(one), dtype=np.int64)


def blocks_mesh(comm, x0, gap, width, height, nx, ny, base_width, base_height, base_nx, base_ny):
    """The slider above y = gap and the base below y = 0: one mesh partitioned by dolfinx over ``comm``."""
    if comm.rank == 0:
        xs, cs = _rectangle([x0, gap], [x0 + width, gap + height], [nx, ny])
        xb, cb = _rectangle([0.0, -base_height], [base_width, 0.0], [base_nx, base_ny])
        x, cells = np.vstack([xs, xb]), np.vstack([cs, cb + len(xs)])
    else:
        x, cells = np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    return create_mesh(comm, cells, x, ufl.Mesh(compat.element("Lagrange", "triangle", 1, (2,))))


def build(comm, width, height, nx, ny, base_width, base_height, base_nx, base_ny, E, nu, rho, gravity, v0, x0, gap):
    """The slider and its base for declared values (see PARAMS)."""
    x0 = 0.5 * (base_width - width) if x0 is None else x0
    msh = blocks_mesh(comm, x0, gap, width, height, nx, ny, base_width, base_height, base_nx, base_ny)
    fdim, tol = msh.topology.dim - 1, 1e-9 * max(width, base_width)

    def on_side(side):
        """Whether points (cells' midpoints) are in the slider (``side`` +1, y > 0) or the base (-1)."""
        return lambda c: side * c[1] > 0.0

    def contact_face(side):
        """The slider's bottom facets (``side`` +1, y = gap) or the base's top ones (-1, y = 0), by their cells."""
        y0 = gap if side > 0 else 0.0
        return facets_where(lambda x: np.abs(x[1] - y0) <= tol, side=on_side(side))

    def cells_of(side):
        return cells_where(on_side(side))

    slave = np.sort(contact_face(1)(msh)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(
        msh, fdim, slave, np.ones(len(slave), dtype=np.int32)))(1)
    lmbda, mu = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))
    weight = fem.Constant(msh, PETSc.ScalarType((0.0, -rho * gravity)))

    def sigma(u):
        return 2.0 * mu * ufl.sym(ufl.grad(u)) + lmbda * ufl.tr(ufl.sym(ufl.grad(u))) * ufl.Identity(2)

    mass = rho * width * height
    return Problem(
        name="sliding_blocks", mesh=msh, shape=(2,), rho=rho,
        a=lambda u, w: ufl.inner(sigma(u), ufl.sym(ufl.grad(w))) * ufl.dx,
        stress=sigma,
        l=lambda w: ufl.inner(weight, w) * ufl.dx,
        u0=lambda x: np.zeros((2, x.shape[1])),
        v0=lambda x: np.vstack([np.where(x[1] > 0.5 * gap, v0, 0.0), 0.0 * x[0]]),
        dirichlet_facets=lambda m: dmesh.locate_entities_boundary(
            m, fdim, lambda x: np.abs(x[1] + base_height) <= tol),
        dirichlet_value=lambda x: np.zeros((2, x.shape[1])),
        constraint_vertices=None, lower_bound=None,
        contact_pairs=[ContactPair(slave=contact_face(1), master=contact_face(-1), name="bottom")],
        bodies=[Body("slider", cells_of(1)), Body("base", cells_of(-1))],
        constraint_component=1,
        constraint_measure=lambda q: q * ds_c,
        probe=(x0 + 0.5 * width, gap),                        # the middle of the slider's bottom face
        extra_columns=("contact_force", "momentum_x", "elastic"),
        momentum_component=0,
        parameters={"width": width, "height": height, "nx": nx, "ny": ny, "base_width": base_width,
                    "base_height": base_height, "base_nx": base_nx, "base_ny": base_ny, "E": E, "nu": nu,
                    "rho": rho, "gravity": gravity, "v0": v0, "x0": x0, "gap": gap, "mass": mass,
                    "lame_lambda": lmbda, "lame_mu": mu},
        units={"width": "mm", "height": "mm", "base_width": "mm", "base_height": "mm", "E": "N/mm^2",
               "rho": "t/mm^3", "gravity": "mm/s^2", "v0": "mm/s", "x0": "mm", "gap": "mm", "mass": "t per mm of thickness",
               "t": "s", "u_probe": "mm", "lambda_probe": "N/mm^2 (>= 0 compressive)",
               "contact_force": "N per mm of thickness", "lame_lambda": "N/mm^2", "lame_mu": "N/mm^2"},
    )


PARAMS = (
    Param("width", 20.0, "width of the slider", unit="mm", low=0.0, low_strict=True),
    Param("height", 10.0, "height of the slider", unit="mm", low=0.0, low_strict=True),
    Param("nx", 10, "squares along the slider's width (two triangles each)", type=int, low=1),
    Param("ny", 5, "squares along the slider's height", type=int, low=1),
    Param("base_width", 60.0, "width of the base", unit="mm", low=0.0, low_strict=True),
    Param("base_height", 10.0, "height of the base", unit="mm", low=0.0, low_strict=True),
    Param("base_nx", 25, "squares along the base's width (not matching the slider's: 2.4 mm against 2 mm)",
          type=int, low=1),
    Param("base_ny", 4, "squares along the base's height", type=int, low=1),
    Param("E", 1000.0, "Young's modulus of both bodies", unit="N/mm^2", low=0.0, low_strict=True),
    Param("nu", 0.0, "Poisson's ratio of both bodies", low=0.0, high=0.49),
    Param("rho", 1e-6, "density of both bodies (1000 kg/m^3)", unit="t/mm^3", low=0.0, low_strict=True),
    Param("gravity", 9810.0, "gravitational acceleration (downward)", unit="mm/s^2", low=0.0),
    Param("v0", 100.0, "initial horizontal velocity of the slider", unit="mm/s"),
    Param("x0", None, "the slider's left end (default: centred on the base)", unit="mm", type=float),
    Param("gap", 0.001, "initial gap between the slider and the base (> 0: the initial velocity tells the bodies "
                       "apart; the slider lands after sqrt(2 gap / g) = 0.45 ms at the defaults)", unit="mm",
          low=0.0, low_strict=True),
)

PROBLEM = ProblemSpec(
    name="sliding_blocks", build=build, params=PARAMS, doc=__doc__,
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 2.5e-5, "T": 0.04, "time_unit": "s"},
)
