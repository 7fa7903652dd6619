"""A plane-strain elastic disc falling on a flat rigid foundation (paper section 5).

Linear elasticity (Lamé lambda, mu) in plane strain, density rho, gravity g downward (or
inclined: below), frictionless unilateral contact (19) with the foundation y = 0 at the
boundary vertices of the potential contact zone. Units: mm, N, s, tonne (so stresses in
N/mm^2 = MPa, densities in t/mm^3, energies in N mm = mJ, all per mm of thickness). Defaults
are those of the paper's original program (Figures 14-16, Table 2): radius 20 mm, point A
(the lowest point) 10 mm above the foundation, rho = 1e-6 t/mm^3, lambda = 300 N/mm^2,
mu = 150 N/mm^2, g = 9810 mm/s^2, initial velocity -1000 mm/s, T = 0.02 s. (Table 1 of
the paper mixes units; these are the consistent values.)

An inclined foundation (--gravity-angle THETA, degrees): gravity g (sin THETA, -cos THETA),
the disc on a foundation inclined at THETA seen in the foundation's frame (x down the
slope). With --height 0 --v0 0 it starts unstressed at rest just touching (and then bounces on
its own weight); --start equilibrium --height 0 --v0 0 starts it resting on the foundation in
static equilibrium under the normal part of gravity (signorini.resting_solution, in the run's
own displacement element), so that the foundation carries m g cos THETA from t = 0 and no
normal vibration starts. A rigid disc (I = m R^2/2) rolls without slipping when the friction
coefficient mu >= tan(THETA)/3, its centre accelerating at (2/3) g sin THETA; it slides when
mu < tan(THETA)/3, its centre at g (sin THETA - mu cos THETA), spinning up at
2 mu g cos THETA / R; frictionless: g sin THETA (see incline_motion). --vx0 adds a horizontal
initial velocity (an oblique impact).
"""
from pathlib import Path
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat

from sdm_dolfinx.problems import base as _problem
from sdm_dolfinx.problems.base import Param, Problem, ProblemSpec
from sdm_dolfinx.problems.block import StaticStart
from sdm_dolfinx.problems.signorini import resting_solution
from sdm_dolfinx.problems import disc_mesh
from sdm_dolfinx.problems.disc_mesh import ALGORITHM, LEVELS, LOWER, make_mesh, read_mesh

#: the potential contact zones: the lower half circle (y <= centre) or the whole boundary
CONTACT_ZONES = ("lower", "all")
#: how the disc starts: unstressed (u0 = 0) at --height with (--vx0, --v0), or resting on the
#: foundation in static equilibrium (signorini.resting_solution) with (--vx0, 0)
STARTS = ("unstressed", "equilibrium")

#: the unit of every parameter and time-series column (for run.json; --help states them too)
UNITS = {"level": "-", "h": "mm (gmsh mesh size)",
         "mesh_file": "- (gmsh .msh or GetFEM .mesh file in mm, read instead of generating)",
         "radius": "mm", "centre": "mm",
         "height": "mm (initial height of the lowest point A above the foundation y = 0)",
         "rho": "t/mm^3", "lame_lambda": "N/mm^2", "lame_mu": "N/mm^2",
         "gravity": "mm/s^2 (magnitude; along (sin theta, -cos theta), theta = gravity_angle: downward at 0)",
         "gravity_angle": "degrees (theta: gravity g (sin theta, -cos theta), at theta to -e_y; the foundation "
                          "inclined at theta, seen in its frame)",
         "v0": "mm/s (vertical, whole disc; < 0 downward)", "vx0": "mm/s (horizontal, whole disc)",
         "spin": "rad/s (counter-clockwise, about the centre)",
         "start": "- (unstressed: u0 = 0; equilibrium: resting on the foundation under (0, -g cos theta))",
         "mass": "t per mm of thickness (rho pi R^2)",
         "probe": "mm (point A, the lowest boundary vertex: u_probe and lambda_probe are recorded there)",
         "t": "s", "dt": "s", "T": "s",
         "energy": "N mm = mJ per mm of thickness (kinetic + elastic + gravity, 0 at rest at t = 0)",
         "kinetic": "N mm", "potential": "N mm (elastic energy minus the work of gravity)",
         "elastic": "N mm (elastic strain energy 1/2 U^T A U)",
         "u_probe": "mm (vertical displacement of A)",
         "lambda_probe": "N/mm^2 (contact stress at A: nodal multiplier / lumped boundary length; >= 0 "
                         "compressive)",
         "contact_force": "N per mm of thickness (sum of the nodal multipliers)",
         "momentum_x": "t mm/s = N s per mm of thickness (e_x^T M Vbar)",
         "momentum_y": "t mm/s = N s per mm of thickness (e_y^T M Vbar)",
         "gap_min_boundary": "mm (min of y + u_y over every displacement dof of the contact boundary, P2 mid-edge "
                             "nodes included; < 0: below the foundation)"}


def sigma(u, lame_lambda, lame_mu):
    """Plane-strain Hooke's law (16): sigma = lambda tr(eps) I + 2 mu eps."""
    eps = ufl.sym(ufl.grad(u))
    return lame_lambda * ufl.tr(eps) * ufl.Identity(len(u)) + 2.0 * lame_mu * eps


def lowest_boundary_vertex(msh, centre_x, tol):
    """(x, y) of the mesh's lowest boundary vertex: point A, where u_probe is recorded. Ties
    (within ``tol``: a flat bottom) go to the vertex nearest to x = ``centre_x``, then to the
    smallest x, so that every rank and every partition picks the same one."""
    comm, tdim = msh.comm, msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    verts = dmesh.locate_entities_boundary(msh, 0, lambda x: np.full(x.shape[1], True))
    x = (msh.geometry.x[compat.entities_to_geometry(msh, 0, verts.astype(np.int32)).reshape(-1)]
         if verts.size else np.zeros((0, 3)))
    ymin = comm.allreduce(float(np.min(x[:, 1], initial=np.inf)), op=MPI.MIN)
    low = np.concatenate(comm.allgather(x[x[:, 1] <= ymin + tol, :2]))      # a few vertices
    off = np.abs(low[:, 0] - centre_x)
    near = low[off <= off.min() + tol]
    a = near[np.argmin(near[:, 0])]
    return float(a[0]), float(a[1])


def _probe(msh, radius, height):
    """Point A for u_probe: the lowest boundary vertex, given as (0, height) when it is there
    (within 1e-8 radius: gmsh's A of the generated meshes), and how run.json describes it."""
    tol = 1e-8 * radius
    a = lowest_boundary_vertex(msh, 0.0, tol)
    if abs(a[0]) <= tol and abs(a[1] - height) <= tol:
        a = (0.0, height)
    return a, f"lowest boundary vertex ({a[0]:.10g}, {a[1]:.10g})"


def gravity_vector(gravity, gravity_angle):
    """The gravity vector g (sin theta, -cos theta) (mm/s^2), theta = ``gravity_angle`` in degrees:
    (0, -g) formed exactly as before the angle existed when theta = 0 (the default disc's runs
    are bit-identical)."""
    if gravity_angle == 0.0:
        return np.array((0.0, -gravity), dtype=PETSc.ScalarType)
    theta = np.deg2rad(gravity_angle)
    return np.array((gravity * np.sin(theta), -gravity * np.cos(theta)), dtype=PETSc.ScalarType)


def _initial_displacement(start, msh, a, load_y, rho, contact_vertices, pins, radius):
    """u0: zero (``unstressed``), or (``equilibrium``) the disc resting on the foundation under
    the load's normal part (0, ``load_y``) (:func:`.signorini.resting_solution`), solved in the
    run's own displacement element (:class:`~sdm_dolfinx.problems.block.StaticStart`)."""
    if start == "unstressed":
        return lambda x: np.zeros((2, x.shape[1]))
    g_n = fem.Constant(msh, np.array((0.0, load_y), dtype=PETSc.ScalarType))

    def l_n(w):
        return rho * ufl.inner(g_n, w) * ufl.dx

    return StaticStart(msh, lambda element, kind: resting_solution(msh, element, a, l_n, contact_vertices(msh), pins,
                                                                   radius),
                       label="disc --start equilibrium", instead="--start unstressed")


def _build(comm, level, h, mesh_file, radius, height, rho, lame_lambda, lame_mu, gravity, gravity_angle, v0, vx0,
           contact_zone, with_contact, start="unstressed", spin=0.0):
    """The disc Problem for declared values (see :data:`SPEC`).

    ``start = "equilibrium"`` (height 0, v0 0: :func:`_check`): U^0 = U_s, the resting solution
    under (0, -g cos theta) in W^h, and Vbar^0 = (vx0, 0). At theta = 0 the frictionless run
    then stays there, translated: U^n = U_s + vx0 t_n e_x with lam = A U_s - L >= 0 at the
    active vertices solves every step's LCP (A e_x = 0; K = alpha^2 M + A is positive definite,
    so it is the only solution), the foundation carries m g and u_probe stays 0 (measured: sum
    lam = m g to 5e-14, tests/physics/test_friction_closed_forms.py). At theta > 0 the
    tangential part of gravity starts the motion down the slope from a disc already pressing on
    the foundation with m g cos theta. (P1 and P1+ displacements on levels 1 and 2, where A alone
    touches, are not quite in equilibrium: their discrete load has a moment of 1e-4 m g R about
    A, which the static solve's second pin takes; sum lam then drifts by 1e-5 m g.)
    """
    if contact_zone not in CONTACT_ZONES:
        raise ValueError(f"unknown contact zone {contact_zone!r}; choose one of {', '.join(CONTACT_ZONES)}")
    cy = radius + height
    if mesh_file is not None:
        level = h = None
        msh, ft = read_mesh(mesh_file, radius, (0.0, cy), comm=comm)
    else:
        level = level if h is None else None        # an explicit h is not a named level
        h = float(LEVELS[level] if h is None else h)
        msh, ft = make_mesh(h, radius=radius, centre=(0.0, cy), comm=comm)
    tdim = msh.topology.dim
    # vertices on the lower half circle: tolerance relative to the radius (gmsh puts the
    # two equator points exactly at y = cy)
    tol = 1e-8 * radius

    def contact_vertices(m):
        if not with_contact:
            return np.zeros(0, dtype=np.int32)
        m.topology.create_connectivity(tdim - 1, tdim)
        if contact_zone == "all":
            return dmesh.locate_entities_boundary(m, 0, lambda x: np.full(x.shape[1], True))
        return dmesh.locate_entities_boundary(m, 0, lambda x: x[1] <= cy + tol)

    ds = ufl.Measure("ds", domain=msh, subdomain_data=ft)
    ds_c = ds if contact_zone == "all" else ds(LOWER)
    # a Constant, not a literal vector: with gravity = 0 UFL would simplify the load form
    # to an empty form (no integration domain)
    g = fem.Constant(msh, gravity_vector(gravity, gravity_angle))
    # a mesh of one's own need not have a vertex at (0, height) (a polygon, rotated): probe A where it is
    probe, probe_text = _probe(msh, radius, height)

    def a(u, w):
        """Plane-strain elasticity (sigma(u), eps(w))."""
        return ufl.inner(sigma(u, lame_lambda, lame_mu), ufl.sym(ufl.grad(w))) * ufl.dx

    u0 = _initial_displacement(start, msh, a, gravity_vector(gravity, gravity_angle)[1], rho, contact_vertices,
                               (probe, (0.0, cy + radius)), radius)

    return _problem.Problem(
        name="disc", mesh=msh, shape=(2,), rho=rho,
        a=a, stress=lambda u: sigma(u, lame_lambda, lame_mu),
        l=lambda w: rho * ufl.inner(g, w) * ufl.dx,
        u0=u0,
        # (vx0, v0) + spin e_z x (x - centre): a rigid motion
        v0=lambda x: np.vstack([vx0 - spin * (x[1] - cy), v0 + spin * x[0]]),
        constraint_vertices=contact_vertices,
        # foundation y = 0: a vertex at height y must keep y + u_y >= 0
        lower_bound=lambda x: -x[1],
        constraint_component=1,
        # lumped length of the contact boundary at each vertex: stress = lambda_i / |Gamma_i|
        constraint_measure=lambda q: q * ds_c,
        dirichlet_facets=None,
        probe=probe,
        extra_columns=("contact_force", "momentum_x", "momentum_y", "elastic"),
        momentum_component=1,
        parameters={"level": level, "h": h, "mesh_file": None if mesh_file is None else str(mesh_file),
                    "radius": radius,
                    "height": height, "centre": [0.0, cy], "rho": rho, "lame_lambda": lame_lambda,
                    "lame_mu": lame_mu, "gravity": gravity, "gravity_angle": gravity_angle, "v0": v0, "vx0": vx0,
                    "spin": spin, "contact_zone": contact_zone, "start": start,
                    "contact_nodes": "vertices", "with_contact": with_contact, "plane": "strain",
                    "gmsh_algorithm": ALGORITHM, "geometry_degree": 2,
                    "mass": rho * np.pi * radius ** 2, "probe": probe_text},
        units=dict(UNITS),
    )


def total_mass(problem):
    """rho |Omega| of the mesh (t per mm of thickness): the discrete mass e^T M e."""
    m = fem.assemble_scalar(compat.form(problem.rho * ufl.dx(domain=problem.mesh)))
    return problem.mesh.comm.allreduce(m, op=MPI.SUM)


def incline_motion(gravity, gravity_angle, mu, radius):
    """The rigid disc's motion on the foundation inclined at theta (closed form, no elasticity).

    A uniform disc of mass m, radius R, moment of inertia I = m R^2/2, resting on the
    foundation with gravity g (sin theta, -cos theta): the normal force is N = m g cos theta,
    the friction force F (along -x when it resists), the centre's acceleration a and the
    angular acceleration alpha (rolling down the slope: positive) obey
        m a = m g sin theta - F,    I alpha = F R.
    Rolling without slipping, a = alpha R: F = I a / R^2 = m a / 2, so a = (2/3) g sin theta and
    F = (1/3) m g sin theta, which Coulomb's law |F| <= mu N allows when mu >= tan(theta)/3.
    Otherwise the contact slides, F = mu N: a = g (sin theta - mu cos theta) and
    alpha = mu m g cos theta R / I = 2 mu g cos theta / R (the contact point slips forward at
    a - alpha R = g (sin theta - 3 mu cos theta) > 0). Frictionless (mu = 0): a = g sin theta,
    alpha = 0.

    Args:
        gravity: g (mm/s^2). gravity_angle: theta (degrees, in [0, 90)).
        mu: the Coulomb friction coefficient (>= 0; 0: frictionless). radius: R (mm).

    Returns:
        ``{"regime": "rolling" | "sliding" | "at rest", "a": centre's acceleration (mm/s^2),
        "alpha": angular acceleration (rad/s^2), "mu_roll": tan(theta)/3}`` (theta = 0: at rest).
    """
    theta = np.deg2rad(gravity_angle)
    mu_roll = np.tan(theta) / 3.0
    if theta == 0.0:
        return {"regime": "at rest", "a": 0.0, "alpha": 0.0, "mu_roll": 0.0}
    if mu >= mu_roll:
        a = 2.0 / 3.0 * gravity * np.sin(theta)
        return {"regime": "rolling", "a": a, "alpha": a / radius, "mu_roll": mu_roll}
    return {"regime": "sliding", "a": gravity * (np.sin(theta) - mu * np.cos(theta)),
            "alpha": 2.0 * mu * gravity * np.cos(theta) / radius, "mu_roll": mu_roll}


#: the disc's parameters, declared once (command line, TOML, run.json, rebuild)
PARAMS = (
    Param("level", 1, "mesh level; P2 dofs close to the paper's Table 2 (622, 2782, 11306, 45706, 126892, 511386)",
          type=int, choices=tuple(sorted(LEVELS))),
    Param("h", None, "gmsh mesh size (overrides --level)", unit="mm", type=float, low=0.0, low_strict=True),
    Param("mesh_file", None, "a mesh file of the disc instead of --level/--h, in mm: gmsh .msh (3- or 6-node "
          "triangles, placed as ours: centre (0, radius + height)) or GetFEM .mesh (GT_PK(2,2) triangles, centre "
          "(0, radius) as in the paper's disc_P2_h*.mesh: moved up by --height); it must be the disc of --radius",
          type=Path, flag="mesh", metavar="FILE"),
    Param("radius", 20.0, "disc radius", unit="mm", low=0.0, low_strict=True),
    Param("height", 10.0, "initial height of the lowest point A above the foundation", unit="mm", low=0.0),
    Param("rho", 1e-6, "density", unit="t/mm^3", low=0.0, low_strict=True),
    Param("lame_lambda", 300.0, "Lamé lambda", unit="N/mm^2"),
    Param("lame_mu", 150.0, "Lamé mu", unit="N/mm^2", low=0.0, low_strict=True),
    Param("gravity", 9810.0, "gravitational acceleration, along (sin theta, -cos theta) (downward at the default "
          "--gravity-angle 0)", unit="mm/s^2"),
    Param("gravity_angle", 0.0, "angle theta in [0, 90) of gravity from -e_y, g (sin theta, -cos theta): the "
          "foundation inclined at theta, seen in its frame (0: the paper's disc)", unit="degrees", low=0.0,
          metavar="THETA"),
    Param("v0", -1000.0, "initial vertical velocity of the disc, negative downward", unit="mm/s"),
    Param("vx0", 0.0, "initial horizontal velocity of the disc (an oblique impact: (vx0, v0))", unit="mm/s"),
    Param("spin", 0.0, "initial angular velocity about the centre, counter-clockwise (rolling to +x without "
          "slipping: -vx0 / radius); needs --contact-zone all", unit="rad/s"),
    Param("contact_zone", "lower", "boundary vertices that may touch: the lower half circle or all", type=str,
          choices=CONTACT_ZONES),
    Param("with_contact", True, "remove the foundation (free flight)", flag="no-contact"),
    Param("start", "unstressed", "initial state: unstressed (u0 = 0) at --height with velocity (--vx0, --v0), or "
          "resting on the foundation in static equilibrium under the normal part of gravity, velocity (--vx0, 0) "
          "(needs --height 0 --v0 0); --spin adds its rotation to either", type=str, choices=STARTS),
)


def _check(values, label):
    errors = []
    if values["mesh_file"] is not None:
        if values["h"] is not None:
            errors.append(f"{label('mesh_file')} and {label('h')}: choose one")
        elif not Path(values["mesh_file"]).is_file():
            errors.append(f"{label('mesh_file')} {values['mesh_file']}: no such file")
    if values["h"] is not None and values["h"] < disc_mesh.MIN_H_RATIO * values["radius"]:
        errors.append(f"{label('h')} must be >= radius / {1 / disc_mesh.MIN_H_RATIO:g} (got {values['h']} mm)")
    if values["h"] is not None and values["h"] > values["radius"]:
        errors.append(f"{label('h')} must be in (0, radius] mm (got {values['h']})")
    resting = values["height"] == 0 and values["v0"] == 0 and values["with_contact"]
    if values["start"] == "equilibrium" and not resting:
        errors.append(f"{label('start')} equilibrium rests the disc on the foundation: it needs {label('height')} 0, "
                      f"{label('v0')} 0 and the foundation (got {label('height')} {values['height']:g}, "
                      f"{label('v0')} {values['v0']:g}{'' if values['with_contact'] else ', no contact'})")
    if values["spin"] != 0.0 and values["with_contact"] and values["contact_zone"] == "lower":
        # a turning disc brings its upper boundary, unconstrained, down to the foundation: it would pass through
        errors.append(f"{label('spin')} turns the disc's upper half, which {label('contact_zone')} lower leaves "
                      f"free to pass through the foundation: give {label('contact_zone')} all")
    if not values["gravity_angle"] < 90.0:
        errors.append(f"{label('gravity_angle')} must be in [0, 90) degrees (got {values['gravity_angle']})")
    if values["lame_lambda"] + values["lame_mu"] <= 0:
        errors.append(f"{label('lame_lambda')} + {label('lame_mu')} must be > 0 in plane strain (got "
                      f"{values['lame_lambda']} + {values['lame_mu']})")
    return errors


SPEC = ProblemSpec(
    name="disc", build=_build, params=PARAMS, check=_check, estimate=disc_mesh.estimate,
    doc=(__doc__ or "").strip(),
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 1e-4, "T": 0.02, "time_unit": "s"},
)


def problem(comm: MPI.Comm = MPI.COMM_WORLD, **values: Any) -> Problem:
    """The paper's falling disc; ``values`` are :data:`PARAMS` (``level``, ``h``, ``mesh_file``,
    ``radius``, ``height``, ``rho``, ``lame_lambda``, ``lame_mu``, ``gravity``, ``gravity_angle``,
    ``v0``, ``vx0``, ``spin``, ``contact_zone``, ``with_contact``, ``start``), the others at their defaults."""
    return SPEC.problem(comm, **values)
