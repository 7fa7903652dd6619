"""An elastic disc sliding in a rigid circular bowl (a problem file with a curved obstacle).

The rigid obstacle is declared as a signed distance (``obstacles``, not ``lower_bound``): the
bowl is everything outside the circle of radius ``Rb`` centred at (0, Rb - r),
``Ball(centre, Rb, inside=True)`` (the body moves inside it). The plane-strain disc of radius
``r`` (centre (0, 0) in the reference configuration, so its lowest point rests at the bottom of
the bowl) starts at rest, unstressed, translated by

    u0 = (Rb - r) (sin theta0, 1 - cos theta0),

so that it touches the bowl at the angle theta0 from its bottom. Gravity g pulls it down; the
contact is frictionless, so the contact force passes through the disc's centre, the disc does not
turn, and its centre moves on the circle of radius L = Rb - r: a pendulum of length L, whose
small-oscillation period is

    T0 = 2 pi sqrt(L / g)      (frictionless; a rigid disc rolling without slipping would give
                                2 pi sqrt(3 L / (2 g))).

With friction (``--friction coulomb --mu 0.5``) the disc rolls, and turns: the linear model is then
valid only for small rotations. Its rotation field u = w x r is strain-free but moves the boundary to
the radius r sqrt(1 + w^2): at the default theta0 the disc turns by about 0.6 rad, grows by 1.7 mm in
the model and gains energy; at theta0 = 1 degree the period is the linear model's
2 pi sqrt(3 L / (2 g (1 + L / r))) (``demos/bowl.py --rolling``, docs/contact.md), not the rigid one.

Every boundary vertex of the disc is constrained: the rows are linearised at the current
configuration every step (sdm_dolfinx/method/obstacle_rows.py), so the contact point moves
around the disc as it swings. The disc is stiff against the swing (its wave transit 2r/c_p is
1/500 of T0 at the defaults), so it moves as a rigid body on a thin elastic contact layer.
``demos/bowl.py`` measures the period. Units: mm, N, s, tonne.
"""
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.problems import Param, Problem, ProblemSpec
from sdm_dolfinx.problems.disc_mesh import make_mesh
from sdm_dolfinx.obstacles import Ball


def period(r, Rb, gravity):
    """T0 = 2 pi sqrt((Rb - r) / g): the frictionless small-oscillation period."""
    return 2.0 * np.pi * np.sqrt((Rb - r) / gravity)


def build(comm, r, Rb, E, nu, rho, gravity, theta0, h):
    msh, _ = make_mesh(h, radius=r, centre=(0.0, 0.0), comm=comm, order=2)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda u: ufl.sym(ufl.grad(u))                                         # noqa: E731
    sigma = lambda u: lmbda * ufl.tr(eps(u)) * ufl.Identity(2) + 2 * mu * eps(u)   # noqa: E731
    g = fem.Constant(msh, PETSc.ScalarType((0.0, -gravity)))
    L, th = Rb - r, np.radians(theta0)
    shift = np.array([L * np.sin(th), L * (1.0 - np.cos(th))])
    on_circle = lambda x: np.isclose(np.hypot(x[0], x[1]), r, atol=1e-6 * r)   # noqa: E731
    facets = np.sort(dmesh.locate_entities_boundary(msh, 1, on_circle)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, 1, facets, np.ones_like(facets)))(1)
    return Problem(
        name="bowl", mesh=msh, shape=(2,), rho=rho, stress=sigma,
        a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx,
        l=lambda w: rho * ufl.inner(g, w) * ufl.dx,
        u0=lambda x: np.tile(shift[:, None], (1, x.shape[1])),
        v0=lambda x: np.zeros((2, x.shape[1])),
        constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, on_circle),
        lower_bound=None, obstacles=[Ball((0.0, Rb - r), Rb, inside=True)],
        constraint_component=1, constraint_measure=lambda q: q * ds_c,
        probe=(0.0, -r), extra_columns=("contact_force", "momentum_x", "momentum_y"),
        parameters={"lame_lambda": lmbda, "lame_mu": mu, "mass": rho * np.pi * r * r,
                    "period": float(period(r, Rb, gravity))},
        units={"t": "s", "u_probe": "mm", "contact_force": "N per mm of thickness", "lame_mu": "N/mm^2",
               "mass": "t per mm of thickness", "period": "s"})


PROBLEM = ProblemSpec(
    name="bowl", build=build, doc=__doc__,
    params=(Param("r", 10.0, "radius of the disc", unit="mm", low=0.0, low_strict=True),
            Param("Rb", 40.0, "radius of the bowl", unit="mm", low=0.0, low_strict=True),
            Param("E", 1000.0, "Young's modulus", unit="N/mm^2", low=0.0, low_strict=True),
            Param("nu", 0.3, "Poisson's ratio", low=0.0, high=0.49),
            Param("rho", 1e-6, "density", unit="t/mm^3", low=0.0, low_strict=True),
            Param("gravity", 9810.0, "gravity", unit="mm/s^2", low=0.0, low_strict=True),
            Param("theta0", 11.5, "initial angle of the contact point from the bottom", unit="degree",
                  low=0.0, high=60.0),
            Param("h", 1.0, "mesh size", unit="mm", low=0.0, low_strict=True)),
    check=lambda v, label: ([f"{label('Rb')} must exceed {label('r')} (the disc moves inside the bowl)"]
                            if v["Rb"] <= v["r"] else []),
    defaults={"pair": "P1+/P0", "dt": 1.75e-4, "T": 0.77, "time_unit": "s"})
