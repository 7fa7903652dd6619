"""An elastic ball falling onto a rigid plane z = 0, checked against Hertz (the 3-D disc).

Linear elasticity (Young's modulus E, Poisson's ratio nu), density rho, a ball of radius R
whose lowest point A starts --height above the plane with the downward speed v; gravity g
along -e_z is off by default (--gravity 9810 for the Earth's); --vt (mm/s, along --vt-angle
degrees from x in the plane) adds a tangential velocity for an oblique impact, with Coulomb
friction (--friction coulomb --mu 0.3; sdm_dolfinx.validation.ball_oblique). Unilateral contact
z + u_z >= 0 at the boundary vertices of the lower hemisphere (as the disc's y + u_y >= 0 in
2-D), frictionless by default. Curved P2 tetrahedra refined toward A (ball_mesh). Units: mm,
N, s, tonne as for the disc (stresses in N/mm^2 = MPa, densities in t/mm^3, forces in N,
energies in N mm = mJ, momenta in t mm/s = N s).

Defaults: R = 20 mm, E = 10 N/mm^2, nu = 0.3, rho = 1e-9 t/mm^3 (1000 kg/m^3), v = 100 mm/s
(0.1 m/s), the issue's choice for Hertz's quasi-static theory: v / c = 1e-3 (c = sqrt(E/rho) =
1e5 mm/s), a / R = 0.08, and the contact lasts t_c = 3.9 ms, 4.8 times the ball's slowest
vibration period (0.81 ms: omega R / c_s = 2.51, c_s = sqrt(mu/rho), the five-fold n = 2
spheroidal mode, measured on level 1 with P2/P2). The ball starts 0.01 mm above the plane
(0.1 ms of flight); dt = 4e-5 s puts ~100 steps in the contact, T = 5 ms sees the rebound.

--R2 (mm) replaces the plane by a rigid sphere of that radius, ``Ball((0, 0, -R2), R2)`` (an
obstacle: gap rows along the sphere's normal, sdm_dolfinx/method/obstacle_rows.py), whose top touches
the plane z = 0 under A: Hertz's two-sphere contact with the second one rigid, the formulas below with
R replaced by R* = 1 / (1/R + 1/R2) (the curvatures add; the mass stays the ball's). Unset, the plane
is the old bound z + u_z >= 0, every run as before.

Hertz's closed forms (:func:`hertz`). A sphere of radius R pressed by a force F onto a rigid
plane (the second body infinitely stiff: 1/E* = (1 - nu^2)/E + 0) approaches it by delta, with
the contact disc of radius a = sqrt(R delta), the pressure p(r) = p0 sqrt(1 - r^2/a^2) and

    F(delta) = 4/3 E* sqrt(R) delta^(3/2),        E* = E / (1 - nu^2).

Quasi-statically the ball of mass m = rho 4/3 pi R^3 moves as a rigid body on this nonlinear
spring: m delta'' = -F(delta), delta(0) = 0, delta'(0) = v. Energy: 1/2 m delta'^2 +
8/15 E* sqrt(R) delta^(5/2) = 1/2 m v^2 (the spring's energy is the integral of F). At the
maximal approach delta' = 0:

    delta_max = (15 m v^2 / (16 E* sqrt(R)))^(2/5),     F_max = 4/3 E* sqrt(R) delta_max^(3/2),

so that 2/5 F_max delta_max = 1/2 m v^2. With s = delta / delta_max the energy gives
delta' = v sqrt(1 - s^(5/2)), and the contact (approach and symmetric release) lasts

    t_c = 2 (delta_max / v) int_0^1 ds / sqrt(1 - s^(5/2)) = (4/5) B(2/5, 1/2) delta_max / v
        ~ 2.9433 delta_max / v

(B the Beta function; the substitution x = s^(5/2) turns the integral into (2/5) B(2/5, 1/2)).
The rebound speed is v (no energy is lost quasi-statically). At maximal compression
a = sqrt(R delta_max) and the peak pressure is p0 = 3 F_max / (2 pi a^2) (the integral of
p over the disc is 2/3 pi a^2 p0). The dynamic correction (the ball's own inertia: its slowest
vibration period is not negligible against t_c) is measured by sdm_dolfinx.validation.hertz: at the
defaults about +3 % on F_max and -2 % on t_c and delta_max against the same mesh at v = 1 mm/s.
"""
import math
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.problems import base as _problem
from sdm_dolfinx.problems import ball_mesh
from sdm_dolfinx.problems.base import Param, Problem, ProblemSpec
from sdm_dolfinx.obstacles import Ball

#: the unit of every parameter and time-series column (for run.json; --help states them too)
UNITS = {"level": "-", "h": "mm (gmsh mesh size far from the contact)",
         "h_contact": "mm (gmsh mesh size near the contact point)", "radius": "mm", "centre": "mm",
         "height": "mm (initial height of the lowest point A above the plane z = 0)",
         "E": "N/mm^2", "nu": "-", "rho": "t/mm^3", "v": "mm/s (initial downward speed, whole ball)",
         "vt": "mm/s (initial tangential speed, whole ball, along vt_angle)",
         "vt_angle": "degrees (direction of vt in the plane, from x towards y)",
         "gravity": "mm/s^2 (along -e_z)", "lame_lambda": "N/mm^2", "lame_mu": "N/mm^2",
         "mass": "t (rho 4/3 pi R^3)", "hertz": "mm, N, s, N/mm^2 (ball.hertz at the impact speed)",
         "probe": "mm (point A, the lowest boundary vertex: u_probe and lambda_probe are recorded there)",
         "t": "s", "dt": "s", "T": "s",
         "energy": "N mm = mJ (kinetic + elastic + gravity)", "kinetic": "N mm",
         "potential": "N mm (elastic energy minus the work of gravity)",
         "elastic": "N mm (elastic strain energy 1/2 U^T A U)", "u_probe": "mm (vertical displacement u_z of A)",
         "lambda_probe": "N/mm^2 (contact pressure at A: nodal multiplier / lumped area; >= 0 compressive)",
         "contact_force": "N (sum of the nodal multipliers: the plane's force on the ball, along +e_z)",
         "momentum_y": "t mm/s = N s (the momentum along z: e_z^T M Vbar, momentum_component = 2)",
         "gap_min_boundary": "mm (min of z + u_z over every displacement dof of the lower hemisphere, P2 "
                             "mid-edge nodes included; < 0: below the plane)"}


def effective_radius(radius, R2=None):
    """Hertz's R* = 1 / (1/R + 1/R2) (mm): R itself on the plane (R2 None)."""
    return radius if R2 is None else 1.0 / (1.0 / radius + 1.0 / R2)


def hertz(radius=20.0, E=10.0, nu=0.3, rho=1e-9, v=100.0, mass=None, R2=None):
    """Hertz's quasi-static impact of an elastic sphere on a rigid plane, or on a rigid sphere of radius
    ``R2`` (derived in the module doc: R becomes R* = 1 / (1/R + 1/R2) in F(delta), the mass stays the ball's).

    Args:
        radius: R (mm). E: Young's modulus (N/mm^2). nu: Poisson's ratio. rho: density (t/mm^3).
        v: impact speed (mm/s, > 0). mass: the mass (t) instead of rho 4/3 pi R^3 (e.g. the mesh's).
        R2: the rigid sphere's radius (mm), None for the plane.

    Returns:
        dict with ``E_star`` (N/mm^2), ``mass`` (t), ``delta_max`` (mm), ``F_max`` (N), ``t_c`` (s),
        ``a`` (mm, the contact radius at delta_max) and ``p0`` (N/mm^2, the peak pressure there).
    """
    E_star = E / (1.0 - nu ** 2)
    m = rho * 4.0 / 3.0 * math.pi * radius ** 3 if mass is None else mass
    r_star = effective_radius(radius, R2)
    k = 4.0 / 3.0 * E_star * math.sqrt(r_star)                     # F = k delta^(3/2)
    delta_max = (15.0 * m * v ** 2 / (16.0 * E_star * math.sqrt(r_star))) ** 0.4
    F_max = k * delta_max ** 1.5
    beta = math.gamma(0.4) * math.gamma(0.5) / math.gamma(0.9)     # B(2/5, 1/2)
    a = math.sqrt(r_star * delta_max)
    return {"E_star": E_star, "mass": m, "delta_max": delta_max, "F_max": F_max,
            "t_c": 0.8 * beta * delta_max / v, "a": a, "p0": 3.0 * F_max / (2.0 * math.pi * a ** 2)}


def hertz_pressure(r, a, p0):
    """Hertz's pressure p0 sqrt(1 - r^2/a^2) at the radii ``r`` (0 outside the contact disc)."""
    r = np.asarray(r, dtype=float)
    return p0 * np.sqrt(np.clip(1.0 - (r / a) ** 2, 0.0, None))


def tangential_velocity(vt, vt_angle):
    """(v_x, v_y) (mm/s) of the tangential speed ``vt`` along ``vt_angle`` degrees from the x axis
    (exact for multiples of 90 degrees: 0 -> (vt, 0))."""
    a = math.radians(vt_angle)
    c, s = (1.0, 0.0) if vt_angle == 0.0 else (math.cos(a), math.sin(a))
    return vt * c, vt * s


def impact_speed(v, gravity, height):
    """The speed at which A reaches the plane: sqrt(v^2 + 2 g height) (mm/s)."""
    return math.sqrt(v ** 2 + 2.0 * gravity * height)


def lame(E, nu):
    """The Lamé parameters (lambda, mu) (N/mm^2) of E and nu (3-D)."""
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def sigma(u, lame_lambda, lame_mu):
    """Hooke's law: sigma = lambda tr(eps) I + 2 mu eps."""
    eps = ufl.sym(ufl.grad(u))
    return lame_lambda * ufl.tr(eps) * ufl.Identity(len(u)) + 2.0 * lame_mu * eps


def lowest_boundary_vertex(msh, tol):
    """(x, y, z) of the mesh's lowest boundary vertex (A); ties within ``tol`` go to the one nearest
    the z axis, then the smallest x, so that every rank and partition picks the same one."""
    comm = msh.comm
    msh.topology.create_connectivity(2, 3)
    verts = dmesh.locate_entities_boundary(msh, 0, lambda x: np.full(x.shape[1], True))
    x = (msh.geometry.x[compat.entities_to_geometry(msh, 0, verts.astype(np.int32)).reshape(-1)]
         if verts.size else np.zeros((0, 3)))
    zmin = comm.allreduce(float(np.min(x[:, 2], initial=np.inf)), op=MPI.MIN)
    low = np.concatenate(comm.allgather(x[x[:, 2] <= zmin + tol]))
    off = np.hypot(low[:, 0], low[:, 1])
    near = low[off <= off.min() + tol]
    return tuple(float(c) for c in near[np.argmin(near[:, 0])])


def mesh_sizes(level, h, h_contact, radius, a):
    """(h, h_contact) in mm: the level's (ball_mesh.sizes), each overridden when given."""
    hf, hc = ball_mesh.sizes(level, radius, a)
    hf = hf if h is None else h
    return hf, min(hf, hc) if h_contact is None else h_contact


def _build(comm, level, h, h_contact, radius, height, E, nu, rho, v, gravity, with_contact, vt=0.0, vt_angle=0.0,
           R2=None):
    """The ball Problem for declared values (see :data:`SPEC`)."""
    cz = radius + height
    ref = hertz(radius, E, nu, rho, impact_speed(v, gravity, height), R2=R2)
    hf, hc = mesh_sizes(level, h, h_contact, radius, ref["a"])
    msh, ft = ball_mesh.make_mesh(hf, hc, ref["a"], radius, (0.0, 0.0, cz), comm=comm)
    tol = 1e-8 * radius
    lmbda, mu = lame(E, nu)
    vx, vy = tangential_velocity(vt, vt_angle)

    def contact_vertices(m):
        if not with_contact:
            return np.zeros(0, dtype=np.int32)
        m.topology.create_connectivity(2, 3)
        return dmesh.locate_entities_boundary(m, 0, lambda x: x[2] <= cz + tol)

    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=ft)(ball_mesh.LOWER)
    # a Constant, not a literal: with gravity 0 UFL would simplify the load to an empty form
    g = fem.Constant(msh, np.array((0.0, 0.0, -gravity), dtype=PETSc.ScalarType))
    probe = lowest_boundary_vertex(msh, tol)
    units = dict(UNITS)
    if R2 is None:                               # the plane z = 0: z + u_z >= 0
        contact = {"lower_bound": lambda x: -x[2]}
    else:                                        # the rigid sphere under A, its top at the origin
        contact = {"lower_bound": None, "obstacles": [Ball((0.0, 0.0, -R2), R2)]}
        units.update(R2="mm (radius of the rigid sphere centred at (0, 0, -R2): its top touches the plane z = 0)",
                     contact_force="N (sum of the nodal multipliers, each along the sphere's normal at its node)",
                     gap_min_boundary="mm (min of the signed distance to the sphere over every displacement dof "
                                      "of the lower hemisphere, P2 mid-edge nodes included; < 0: inside it)")
    return _problem.Problem(
        name="ball", mesh=msh, shape=(3,), rho=rho,
        a=lambda u, w: ufl.inner(sigma(u, lmbda, mu), ufl.sym(ufl.grad(w))) * ufl.dx,
        l=lambda w: rho * ufl.inner(g, w) * ufl.dx,
        u0=lambda x: np.zeros((3, x.shape[1])),
        v0=lambda x: np.vstack([np.full(x.shape[1], vx), np.full(x.shape[1], vy), np.full(x.shape[1], -v)]),
        constraint_vertices=contact_vertices,
        constraint_component=2,
        constraint_measure=lambda q: q * ds_c,       # lumped area: pressure = lambda_i / |Gamma_i|
        probe=probe,
        extra_columns=("contact_force", "momentum_y", "elastic"),
        momentum_component=2, **contact,
        parameters={"level": level if h is None and h_contact is None else None, "h": hf, "h_contact": hc,
                    "radius": radius, "height": height, "centre": [0.0, 0.0, cz], "E": E, "nu": nu, "rho": rho,
                    "v": v, "vt": vt, "vt_angle": vt_angle, "gravity": gravity, "with_contact": with_contact, "R2": R2,
                    "lame_lambda": lmbda, "lame_mu": mu, "contact_nodes": "vertices", "geometry_degree": 2,
                    "mass": rho * 4.0 / 3.0 * math.pi * radius ** 3, "hertz": ref,
                    "probe": "lowest boundary vertex ({:.10g}, {:.10g}, {:.10g})".format(*probe)},
        units=units)


def total_mass(problem):
    """rho |Omega| of the mesh (t): the discrete mass e^T M e (curved P2 cells: within O(h^4)
    of rho 4/3 pi R^3)."""
    m = fem.assemble_scalar(compat.form(problem.rho * ufl.dx(domain=problem.mesh)))
    return problem.mesh.comm.allreduce(m, op=MPI.SUM)


PARAMS = (
    Param("level", 1, "mesh level: far size R / (2, 3, 4, 5, 6, 9), contact size a / (2, 4, 6, 8, 12, 18), a the "
          "Hertz contact radius (P2 dofs at the defaults: 6594, 21750, 53976, 107397, 291501, 890127)", type=int,
          choices=tuple(sorted(ball_mesh.LEVELS))),
    Param("h", None, "gmsh mesh size far from the contact (overrides the level's)", unit="mm", type=float,
          low=0.0, low_strict=True),
    Param("h_contact", None, "gmsh mesh size at the contact point (overrides the level's)", unit="mm", type=float,
          low=0.0, low_strict=True),
    Param("radius", 20.0, "ball radius", unit="mm", low=0.0, low_strict=True),
    Param("height", 0.01, "initial height of the lowest point A above the plane", unit="mm", low=0.0),
    Param("E", 10.0, "Young's modulus", unit="N/mm^2", low=0.0, low_strict=True),
    Param("nu", 0.3, "Poisson's ratio", low=0.0, high=0.49),
    Param("rho", 1e-9, "density (1e-9 t/mm^3 = 1000 kg/m^3)", unit="t/mm^3", low=0.0, low_strict=True),
    Param("v", 100.0, "initial downward speed of the ball", unit="mm/s", low=0.0, low_strict=True),
    Param("vt", 0.0, "initial tangential speed of the ball (along --vt-angle in the plane; an oblique "
          "impact with --friction coulomb --mu MU)", unit="mm/s"),
    Param("vt_angle", 0.0, "direction of --vt in the plane z = 0, from the x axis towards y", unit="degrees",
          low=-360.0, high=360.0),
    Param("gravity", 0.0, "gravitational acceleration along -e_z (0: off; 9810 for the Earth's)", unit="mm/s^2",
          low=0.0),
    Param("with_contact", True, "remove the plane (free flight)", flag="no-contact"),
    Param("R2", None, "radius of a rigid sphere under the ball in place of the plane z = 0 (centred at "
          "(0, 0, -R2): its top touches the plane; Hertz with 1/R* = 1/R + 1/R2; unset: the plane)", unit="mm",
          type=float, low=0.0, low_strict=True),
)


def _check(values, label):
    errors = []
    ref = hertz(values["radius"], values["E"], values["nu"], values["rho"],
                impact_speed(values["v"], values["gravity"], values["height"]), R2=values.get("R2"))
    if values.get("R2") is not None and not values["with_contact"]:
        errors.append(f"{label('R2')} (a rigid sphere to hit) means nothing with {label('with_contact')} off")
    hf, hc = mesh_sizes(values["level"], values["h"], values["h_contact"], values["radius"], ref["a"])
    if not ball_mesh.MIN_H_RATIO * values["radius"] <= hc <= hf <= values["radius"]:
        errors.append(f"mesh sizes must satisfy radius / {1 / ball_mesh.MIN_H_RATIO:g} <= {label('h_contact')} <= "
                      f"{label('h')} <= {label('radius')} (got {hc:g} <= {hf:g} <= {values['radius']:g} mm)")
    return errors


def _estimate(values):
    """The mesh a ball run makes, counted without gmsh (ball_mesh.estimate_mesh), for launch's memory check."""
    ref = hertz(values["radius"], values["E"], values["nu"], values["rho"],
                impact_speed(values["v"], values["gravity"], values["height"]), R2=values.get("R2"))
    hf, hc = mesh_sizes(values["level"], values["h"], values["h_contact"], values["radius"], ref["a"])
    by = tuple(n for n in ("h", "h_contact") if values.get(n) is not None) or ("level",)
    return {**ball_mesh.estimate_mesh(hf, hc, ref["a"], values["radius"]), "value_size": 3, "by": by}


SPEC = ProblemSpec(
    name="ball", build=_build, params=PARAMS, check=_check, estimate=_estimate, doc=(__doc__ or "").strip(),
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 4e-5, "T": 5e-3, "time_unit": "s"})


def problem(comm: MPI.Comm = MPI.COMM_WORLD, **values: Any) -> Problem:
    """The falling ball; ``values`` are :data:`PARAMS` (``level``, ``h``, ``h_contact``, ``radius``,
    ``height``, ``E``, ``nu``, ``rho``, ``v``, ``vt``, ``vt_angle``, ``gravity``, ``with_contact``, ``R2``), the
    others at
    their defaults."""
    return SPEC.problem(comm, **values)


def hertz_of(problem, mesh_mass=False):
    """:func:`hertz` for a built ball Problem at its impact speed (``mesh_mass``: with the mesh's mass)."""
    p = problem.parameters
    return hertz(p["radius"], p["E"], p["nu"], p["rho"], impact_speed(p["v"], p["gravity"], p["height"]),
                 mass=total_mass(problem) if mesh_mass else None, R2=p.get("R2"))
