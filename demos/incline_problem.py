"""An elastic block resting on an incline, started at its static equilibrium (a problem file).

The rigid foundation is the plane {last coordinate = 0} (y = 0 in 2-D, plane strain; z = 0 in
3-D), and the incline is made by tilting gravity by ``theta``: g = 9810 (sin theta, 0, ..., -cos
theta) mm/s^2, downhill along +x. With Coulomb friction mu > tan theta a rigid block sticks; an
elastic one started unstressed (``--start rest``) rattles on the foundation and creeps, while
``--start equilibrium`` (``u0 = "equilibrium"``: the static Signorini solution of the run's own
discretisation, with the run's constraint kind and friction) starts it at rest with the
foundation carrying m g cos theta normally and m g sin theta tangentially, and it stays there:

    python -m sdm_dolfinx run --problem-file demos/incline_problem.py --friction coulomb --mu 0.8
    python -m sdm_dolfinx run --problem-file demos/incline_problem.py --dim 3 --pair P1/P1 \\
        --friction coulomb --mu 0.8 --start rest          # rattles and creeps

Without friction (or with mu <= tan theta everywhere) nothing holds the block along the
incline, and the equilibrium start is refused in one line. Units: mm, N, s, tonne.
"""
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.problems import Param, Problem, ProblemSpec


def build(comm, dim, width, height, E, nu, rho, theta, n, start):
    """The block [0, width]^(dim-1) x [0, height] on the foundation {last coordinate = 0}."""
    layers = max(1, round(n * height / width))
    if dim == 2:
        msh = dmesh.create_rectangle(comm, [np.zeros(2), np.array([width, height])], [n, layers],
                                     dmesh.CellType.triangle)
    else:
        msh = dmesh.create_box(comm, [np.zeros(3), np.array([width, width, height])], [n, n, layers],
                               dmesh.CellType.tetrahedron)
    fdim, c = msh.topology.dim - 1, dim - 1             # c: the normal component of the foundation
    bottom = lambda x: np.isclose(x[c], 0.0)            # noqa: E731
    facets = np.sort(dmesh.locate_entities_boundary(msh, fdim, bottom)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, fdim, facets, np.ones_like(facets)))(1)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda u: ufl.sym(ufl.grad(u))                # noqa: E731
    sigma = lambda u: lmbda * ufl.tr(eps(u)) * ufl.Identity(dim) + 2 * mu * eps(u)   # noqa: E731
    g = np.zeros(dim)
    g[0], g[c] = 9810.0 * np.sin(np.radians(theta)), -9810.0 * np.cos(np.radians(theta))
    gravity = fem.Constant(msh, PETSc.ScalarType(g))
    zero = lambda x: np.zeros((dim, x.shape[1]))        # noqa: E731
    return Problem(
        name="incline", mesh=msh, shape=(dim,), rho=rho,
        a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx,
        l=lambda w: rho * ufl.inner(gravity, w) * ufl.dx,
        u0="equilibrium" if start == "equilibrium" else zero,   # the static solution, or unstressed
        v0=zero,
        constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom),
        lower_bound=lambda x: -x[c],                    # x_c + u_c >= 0: the foundation
        constraint_component=c,
        constraint_measure=lambda q: q * ds_c,
        probe=(width / 2, 0.0) if dim == 2 else (width / 2, width / 2, 0.0), stress=sigma,
        extra_columns=("contact_force", "momentum_x"),
        parameters={"lame_lambda": lmbda, "lame_mu": mu, "mass": rho * width ** (dim - 1) * height},
        units={"t": "s", "u_probe": "mm", "contact_force": "N (per mm of thickness in 2-D)",
               "lame_mu": "N/mm^2", "mass": "t (per mm of thickness in 2-D)"})


PROBLEM = ProblemSpec(
    name="incline", build=build, doc=__doc__,
    params=(Param("dim", 2, "dimension: 2 (plane strain) or 3", type=int, choices=(2, 3)),
            Param("width", 10.0, "width (and depth in 3-D)", unit="mm", low=0.0, low_strict=True),
            Param("height", 10.0, "height", unit="mm", low=0.0, low_strict=True),
            Param("E", 1000.0, "Young's modulus", unit="N/mm^2", low=0.0, low_strict=True),
            Param("nu", 0.3, "Poisson's ratio", low=0.0, high=0.49),
            Param("rho", 1e-6, "density", unit="t/mm^3", low=0.0, low_strict=True),
            Param("theta", 30.0, "inclination of the foundation (gravity tilted by it)", unit="degree",
                  low=0.0, high=89.0),
            Param("n", 4, "cells along the width", type=int, low=1),
            Param("start", "equilibrium", "initial state: the static equilibrium (u0 = 'equilibrium') or "
                  "unstressed at rest on the foundation", type=str, choices=("equilibrium", "rest"))),
    defaults={"pair": "P2/P1", "dt": 1e-4, "T": 2e-3, "time_unit": "s"})
