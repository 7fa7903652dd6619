"""An elastic bar hitting a rigid wall: a problem file (not part of the package).

A problem file declares ``PROBLEM = ProblemSpec(...)``: its parameters once (default, unit,
bounds, help) and a ``build(comm, **values)`` returning a :class:`sdm_dolfinx.problems.Problem`.
With it the problem has every command the paper's membrane and disc have:

    python -m sdm_dolfinx run --problem-file demos/bar_problem.py --Nx 40 --out output/bar
    python -m sdm_dolfinx run --restart output/bar          (after a Ctrl-C)
    python -m sdm_dolfinx energy output/bar
    python -m sdm_dolfinx inspect --problem-file demos/bar_problem.py --Nx 20 --pair P2/P1

and in Python ``sdm_dolfinx.simulate("demos/bar_problem.py", {"Nx": 40}, out=...)``.

The bar [d, d + L] x [0, H] moves with velocity -v toward the wall x = 0, which its end face
reaches at t0 = d / v. Frictionless contact x + u_x >= 0 at the vertices of that face. With
Poisson's ratio 0 (Lamé lambda = 0, E = 2 mu) the 2-D solution is exactly the 1-D one: the
contact lasts 2 L / c, c = sqrt(E / rho), at the stress rho c v (see demos/custom_problem.py).
Units: mm, N, s, tonne; defaults: a steel bar, L = 100 mm, H = 10 mm, E = 200 GPa,
rho = 7850 kg/m^3, v = 1 m/s (c = 5048 m/s, 2L/c = 39.6 us, rho c v = 39.6 MPa).
"""
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.problems import Param, Problem, ProblemSpec
from sdm_dolfinx.problems.bar import plane_exact


def sigma(u, lame_mu):
    """Hooke's law with Lamé lambda = 0 (Poisson's ratio 0): sigma = 2 mu eps(u)."""
    return 2.0 * lame_mu * ufl.sym(ufl.grad(u))


def build(comm, L, H, E, rho, v, Nx, Ny, gap_time):
    """The bar for declared values (see PARAMS)."""
    c = np.sqrt(E / rho)
    t0 = 0.1 * 2.0 * L / c if gap_time is None else gap_time
    d = v * t0
    msh = dmesh.create_rectangle(comm, [np.array([d, 0.0]), np.array([d + L, H])], [Nx, Ny],
                                 dmesh.CellType.triangle)
    fdim = msh.topology.dim - 1

    def on_end_face(x):
        return np.isclose(x[0], d, rtol=0.0, atol=1e-9 * L)

    # the end face x = d, tagged 1: the contact stress at a vertex is its nodal multiplier
    # divided by its share of the face's length (the integral of its hat function on the face)
    facets = np.sort(dmesh.locate_entities_boundary(msh, fdim, on_end_face)).astype(np.int32)
    tags = dmesh.meshtags(msh, fdim, facets, np.full(len(facets), 1, dtype=np.int32))
    ds_end = ufl.Measure("ds", domain=msh, subdomain_data=tags)(1)
    zero = fem.Constant(msh, PETSc.ScalarType((0.0, 0.0)))
    lame_mu = E / 2.0

    return Problem(
        name="plane_bar", mesh=msh, shape=(2,), rho=rho,
        a=lambda u, w: ufl.inner(sigma(u, lame_mu), ufl.sym(ufl.grad(w))) * ufl.dx,
        l=lambda w: ufl.inner(zero, w) * ufl.dx,                  # no body force
        u0=lambda x: np.zeros((2, x.shape[1])),
        v0=lambda x: np.vstack([np.full(x.shape[1], -v), np.zeros(x.shape[1])]),
        constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, on_end_face),
        lower_bound=lambda x: -x[0],                               # x + u_x >= 0: the wall x = 0
        constraint_component=0,
        constraint_measure=lambda q: q * ds_end,
        probe=(d, H / 2.0),                                        # the middle of the end face
        extra_columns=("contact_force",),
        parameters={"L": L, "H": H, "E": E, "nu": 0.0, "lame_lambda": 0.0, "lame_mu": lame_mu, "rho": rho,
                    "v": v, "gap": d, "gap_time": t0, "Nx": Nx, "Ny": Ny, "c": c},
        units={"L": "mm", "H": "mm", "E": "N/mm^2", "rho": "t/mm^3", "v": "mm/s", "gap": "mm", "t": "s",
               "lambda_probe": "N/mm^2 (>= 0 compressive)", "contact_force": "N per mm of thickness"},
    )


PARAMS = (
    Param("L", 100.0, "length of the bar", unit="mm", low=0.0, low_strict=True),
    Param("H", 10.0, "height of the bar", unit="mm", low=0.0, low_strict=True),
    Param("E", 2.0e5, "Young's modulus (Poisson's ratio 0)", unit="N/mm^2", low=0.0, low_strict=True),
    Param("rho", 7.85e-9, "density", unit="t/mm^3", low=0.0, low_strict=True),
    Param("v", 1000.0, "speed toward the wall", unit="mm/s", low=0.0, low_strict=True),
    Param("Nx", 40, "cells along the bar (each split into two triangles)", type=int, low=1),
    Param("Ny", 4, "cells across the bar", type=int, low=1),
    Param("gap_time", None, "time at which the end face reaches the wall (default: a tenth of 2L/c)", unit="s",
          type=float, low=0.0),
)

PROBLEM = ProblemSpec(
    name="plane_bar", build=build, params=PARAMS, doc=__doc__,
    exact=plane_exact,          # nu = 0: the 1-D closed form of the built-in bar (sdm_dolfinx/problems/bar.py)
    # dt = h / (2c) and T = t0 + 1.5 x 2L/c for the defaults (Nx = 40)
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 2.5e-7, "T": 6.5e-5, "time_unit": "s"},
)
