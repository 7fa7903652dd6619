"""A rigid cylinder (a disc in plane strain) pressed slowly into an elastic block: Hertz's line contact.

A problem file (docs/add_a_problem.md) with a moving curved obstacle, run by demos/indent.py and
tests/physics/test_obstacle_hertz.py. The block [-L, L] x [-H, 0] (plane strain, E, nu, rho) is
clamped on its bottom (a Dirichlet part ``bottom``, u = 0: its reaction columns ``reaction_bottom_x``,
``reaction_bottom_y``) and free on its sides; its top y = 0 is the contact boundary (frictionless).
The rigid disc ``Ball((0, R), R, motion=t -> (0, -d(t)))`` touches the top at the origin at t = 0,
with the body unstressed and at rest, and is moved down by the smooth ramp

    d(t) = depth (1 - cos(pi t / ramp)) / 2   for t < ramp,   depth afterwards,

slow against the block's wave transit 2 H / c_p (c_p = sqrt((lambda + 2 mu) / rho)): at the defaults
ramp = 100 ms, 2 H / c_p = 1.1 ms, so the push is quasi-static (the kinetic energy is compared with
the elastic one by the test and the demo).

Why the obstacle moves and the block stands (rather than the block pushed up onto a fixed disc by
its bottom): the pushing is then done by the very object whose force we compare, the obstacle's
work enters the column ``obstacle_work``, and the clamp that holds the block is a fixed Dirichlet
part whose reaction is an independent measure of the load (quasi-statically P = reaction_bottom_y).

Closed form (Hertz, line contact, per mm of thickness). A rigid cylinder of radius R pressed by the
load P per unit length into an elastic half-plane (E* = E / (1 - nu^2): the cylinder rigid, so
1/E* = (1 - nu^2)/E + 0) makes the contact zone |x| < a with

    a^2 = 4 P R / (pi E*),   p(x) = (2 P / (pi a^2)) sqrt(a^2 - x^2),

valid for a << R (the cylinder's surface replaced by its parabola y = x^2 / (2R)) and a << L, H
(the block a half-plane: its size enters the approach d, which has no closed form of its own in
2-D, not the half-width to first order). P is the contact force (the column ``contact_force``: the
sum of the nodal multipliers, each along the obstacle's normal at its node; quasi-statically equal
to the clamp's vertical reaction). :func:`hertz_half_width` evaluates a; :class:`ContactZone`
measures it during a run.

The mesh (gmsh, built on one rank, straight triangles) has the size ``h`` within ``fine`` of the
origin and ``coarse`` further than 3 ``fine``, growing linearly between them; the origin is a vertex.
Units: mm, N, s, tonne (E in N/mm^2 = MPa).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.obstacles import Ball
from sdm_dolfinx.problems import DirichletPart, Param, Problem, ProblemSpec

#: gmsh physical groups of the boundary: top (contact), bottom (clamped), sides (free)
TOP, BOTTOM, SIDES = 1, 2, 3


def hertz_half_width(P, R, E, nu):
    """a = sqrt(4 P R / (pi E*)), E* = E / (1 - nu^2): Hertz's half-width for the load P per mm."""
    return np.sqrt(4.0 * np.asarray(P, dtype=float) * R / (np.pi * E / (1.0 - nu * nu)))


def push(t, depth, ramp):
    """d(t): the smooth ramp (1 - cos(pi t / ramp)) / 2 to ``depth``, then held."""
    s = np.clip(np.asarray(t, dtype=float) / ramp, 0.0, 1.0)
    return depth * 0.5 * (1.0 - np.cos(np.pi * s))


def push_rate(t, depth, ramp):
    """d'(t) of :func:`push` (the obstacle's exact velocity: no finite difference)."""
    s = np.asarray(t, dtype=float) / ramp
    return np.where((s > 0) & (s < 1), depth * 0.5 * np.pi / ramp * np.sin(np.pi * s), 0.0)


class ContactZone:
    """``observe`` callback: after every step, on rank 0, the contact zone's bounds (a_in, a_out)
    (``rows``) and the last step's nodes and nodal pressures (``last``: x, lam_i / |Gamma_i|).

    The zone is where the nodal multiplier lam_i > 0. Its edge lies between the outermost node with
    lam > 0 and the next node outward, which is free: a_in is half the extent of the active nodes,
    a_out half the distance between the first free nodes on either side; a = (a_in + a_out) / 2 is
    uncertain by +-(a_out - a_in) / 2, half the node spacing (h / 2 at the vertices). The nodes'
    reference x is used (their horizontal displacement, ~1e-3 a here, is far below h).
    """

    def __init__(self, comm=MPI.COMM_WORLD):
        self.comm, self.rows, self.last = comm, [], None

    def __call__(self, state):
        d = state.discretisation
        pieces = self.comm.gather((d.cx[0].copy(), np.asarray(state.lam).copy(), np.asarray(d.cmeasure).copy()),
                                  root=0)
        if self.comm.rank != 0:
            return
        x, lam, meas = (np.concatenate([p[k] for p in pieces]) for k in range(3))
        on = lam > 0.0
        if not on.any():
            self.rows.append((0.0, 0.0))
            return
        left, right = x[on].min(), x[on].max()
        free_left = x[~on & (x < left)].max(initial=-np.inf)
        free_right = x[~on & (x > right)].min(initial=np.inf)
        self.rows.append((0.5 * (right - left), 0.5 * (free_right - free_left)))
        self.last = (x, lam / meas)


def make_mesh(comm, L, H, h, fine, coarse):
    """(mesh, facet tags): the block [-L, L] x [-H, 0], the origin a vertex, size h near it."""
    if comm.rank == 0:
        import gmsh
        owner = not getattr(gmsh, "isInitialized", lambda: False)()     # gmsh < 4.9 cannot tell
        if owner:
            gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("indent")
        geo = gmsh.model.geo
        corners = [(-L, -H), (L, -H), (L, 0.0), (0.0, 0.0), (-L, 0.0)]
        pts = [geo.addPoint(x, y, 0.0, coarse) for x, y in corners]
        lines = [geo.addLine(pts[i], pts[(i + 1) % 5]) for i in range(5)]
        surf = geo.addPlaneSurface([geo.addCurveLoop(lines)])
        geo.synchronize()
        gmsh.model.addPhysicalGroup(2, [surf], 1)
        gmsh.model.addPhysicalGroup(1, [lines[2], lines[3]], TOP)
        gmsh.model.addPhysicalGroup(1, [lines[0]], BOTTOM)
        gmsh.model.addPhysicalGroup(1, [lines[1], lines[4]], SIDES)
        f = gmsh.model.mesh.field
        dist = f.add("Distance")
        f.setNumbers(dist, "PointsList", [pts[3]])
        thr = f.add("Threshold")
        f.setNumber(thr, "InField", dist)
        for k, v in (("SizeMin", h), ("SizeMax", coarse), ("DistMin", fine), ("DistMax", 3.0 * fine)):
            f.setNumber(thr, k, v)
        f.setAsBackgroundMesh(thr)
        for k, v in (("MeshSizeFromPoints", 0), ("MeshSizeFromCurvature", 0), ("MeshSizeExtendFromBoundary", 0),
                     ("Algorithm", 6)):
            gmsh.option.setNumber(f"Mesh.{k}", v)
        gmsh.model.mesh.generate(2)
        msh, _, ft = compat.model_to_mesh(gmsh.model, comm, 0, gdim=2)
        gmsh.finalize() if owner else gmsh.model.remove()           # a caller's session left open
    else:
        msh, _, ft = compat.model_to_mesh(None, comm, 0, gdim=2)
    return msh, ft


def build(comm, R, L, H, E, nu, rho, depth, ramp, h, fine, coarse):
    msh, ft = make_mesh(comm, L, H, h, fine, coarse)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda u: ufl.sym(ufl.grad(u))                                        # noqa: E731
    sigma = lambda u: lmbda * ufl.tr(eps(u)) * ufl.Identity(2) + 2 * mu * eps(u)  # noqa: E731
    zero = fem.Constant(msh, np.zeros(2, dtype=PETSc.ScalarType))              # no body force
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=ft)(TOP)
    bottom_facets = ft.indices[ft.values == BOTTOM]
    clamp = DirichletPart("bottom", lambda m: bottom_facets, value=lambda x, t: np.zeros((2, x.shape[1])))
    cylinder = Ball((0.0, R), R, motion=lambda t: (0.0, -float(push(t, depth, ramp))),
                    motion_velocity=lambda t: (0.0, -float(push_rate(t, depth, ramp))))
    c_p = float(np.sqrt((lmbda + 2 * mu) / rho))
    return Problem(
        name="indent", mesh=msh, shape=(2,), rho=rho, stress=sigma,
        a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx,
        l=lambda w: ufl.inner(zero, w) * ufl.dx,
        u0=lambda x: np.zeros((2, x.shape[1])), v0=lambda x: np.zeros((2, x.shape[1])),
        constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, lambda x: np.isclose(x[1], 0.0)),
        lower_bound=None, obstacles=[cylinder], constraint_component=1,
        constraint_measure=lambda q: q * ds_c,
        dirichlet_parts=[clamp],
        probe=(0.0, 0.0), extra_columns=("contact_force", "elastic"),
        parameters={"lame_lambda": lmbda, "lame_mu": mu, "E_star": E / (1 - nu * nu), "c_p": c_p,
                    "transit": 2 * H / c_p},
        units={"t": "s", "E_star": "N/mm^2", "c_p": "mm/s", "transit": "s (2H / c_p)",
               "contact_force": "N per mm of thickness", "reaction_bottom_x": "N per mm of thickness",
               "reaction_bottom_y": "N per mm of thickness", "obstacle_work": "N mm per mm of thickness",
               "elastic": "N mm per mm of thickness"})


PROBLEM = ProblemSpec(
    name="indent", build=build, doc=__doc__,
    params=(Param("R", 20.0, "radius of the rigid cylinder", unit="mm", low=0.0, low_strict=True),
            Param("L", 20.0, "half-width of the block", unit="mm", low=0.0, low_strict=True),
            Param("H", 20.0, "depth of the block", unit="mm", low=0.0, low_strict=True),
            Param("E", 1000.0, "Young's modulus", unit="N/mm^2", low=0.0, low_strict=True),
            Param("nu", 0.3, "Poisson's ratio", low=0.0, high=0.49),
            Param("rho", 1e-6, "density", unit="t/mm^3", low=0.0, low_strict=True),
            Param("depth", 0.4, "the cylinder's descent d at the end of the ramp", unit="mm", low=0.0),
            Param("ramp", 0.1, "duration of the ramp", unit="s", low=0.0, low_strict=True),
            Param("h", 0.125, "mesh size near the first contact point", unit="mm", low=0.0, low_strict=True),
            Param("fine", 2.5, "radius of the zone of size h", unit="mm", low=0.0, low_strict=True),
            Param("coarse", 2.5, "mesh size far from the contact", unit="mm", low=0.0, low_strict=True)),
    check=lambda v, label: ([f"{label('depth')} must be below {label('R')} / 10 (Hertz: a << R)"]
                            if v["depth"] >= 0.1 * v["R"] else []),
    defaults={"pair": "P1+/P0", "dt": 1e-3, "T": 0.1, "time_unit": "s"})
