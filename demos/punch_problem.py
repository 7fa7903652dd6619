"""An elastic disc pressed onto a rigid flat foundation by a prescribed displacement of its top.

A displacement-controlled Hertz line contact (a problem file: docs/add_a_problem.md), run by
demos/punch.py. The roles of Hertz's cylinder and half-plane are inverted, which the theory
allows: here the cylinder is elastic and the flat is rigid. The plane-strain disc of radius R
(centre (0, R)) touches the frictionless foundation y = 0 at its lowest point A at t = 0,
unstressed and at rest; a small arc at its top (the facets within ``arc`` degrees of the top
point) is a Dirichlet part ``top`` moved down by d(t) in y and held at 0 in x. Both components
are prescribed: with the y component only, the frictionless contact would leave the disc free to
translate sideways and to rotate (A alone holds neither), so the static problem would have no
unique solution and any asymmetry of the mesh would let the disc drift; the top arc held in x
removes those rigid motions. Holding it in x also bonds the arc (a stiffer, rougher punch than a
frictionless one), which does not matter for the contact zone 2R away (Saint-Venant). The push
is a smooth ramp starting at rest,

    d(t) = depth (1 - cos(pi t / ramp)) / 2   for t < ramp,   depth afterwards,

slow against the disc's wave transit 2R / c_p (c_p = sqrt((lambda + 2 mu) / rho)): at the
defaults ramp = 200 ms and 2R / c_p = 1.1 ms, so the motion is quasi-static (demos/punch.py
measures the kinetic energy against the elastic one).

Closed form (Hertz, line contact, per mm of thickness). For a contact half-width a << R, an
elastic cylinder of radius R pressed on a rigid flat by the load P per unit length has

    a^2 = 4 P R / (pi E*),   E* = E / (1 - nu^2)   (the flat rigid: 1/E* = (1 - nu^2)/E + 0),

with the elliptic pressure p(x) = (2 P / (pi a^2)) sqrt(a^2 - x^2). P is the contact force
(the column ``contact_force``, the sum of the nodal multipliers), which quasi-statically equals
minus ``reaction_top_y``. The approach d of a 2-D indentation has no closed form independent of
how and where the load is applied (the logarithm of a line load: it depends on the body's size),
so demos/punch.py shows P(d) as measured. :func:`hertz_half_width` evaluates a.

The mesh (gmsh, built on one rank, curved quadratic triangles) has the size ``h`` (mm) within
``fine`` mm of A and ``coarse`` further than 3 ``fine``, growing linearly between them; A is a
vertex. The contact is checked at the boundary vertices of the lower half circle.
Units: mm, N, s, tonne (E in N/mm^2 = MPa).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.problems import DirichletPart, Param, Problem, ProblemSpec

#: gmsh physical groups of the boundary: lower half circle, upper half circle but the top arc, top arc
LOWER, UPPER, TOP = 1, 2, 3


def hertz_half_width(P, R, E, nu):
    """a = sqrt(4 P R / (pi E*)), E* = E / (1 - nu^2): Hertz's half-width for the load P per mm."""
    return np.sqrt(4.0 * np.asarray(P, dtype=float) * R / (np.pi * E / (1.0 - nu * nu)))


def push(t, depth, ramp):
    """d(t): the smooth ramp (1 - cos(pi t / ramp)) / 2 to ``depth``, then held."""
    s = np.clip(np.asarray(t, dtype=float) / ramp, 0.0, 1.0)
    return depth * 0.5 * (1.0 - np.cos(np.pi * s))


def make_mesh(comm, R, h, fine, coarse, arc):
    """(mesh, facet tags): the disc of radius R centred at (0, R), A = (0, 0) a vertex, the top arc
    (``arc`` degrees either side of the top) a curve of its own; size h near A (see the module)."""
    if comm.rank == 0:
        import gmsh
        owner = not getattr(gmsh, "isInitialized", lambda: False)()     # gmsh < 4.9 cannot tell
        if owner:
            gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("punch")
        geo = gmsh.model.geo
        c = geo.addPoint(0.0, R, 0.0, coarse)
        b = np.deg2rad(arc)
        angles = (-np.pi / 2, 0.0, np.pi / 2 - b, np.pi / 2 + b, np.pi)       # A, right, top arc, left
        pts = [geo.addPoint(R * np.cos(t), R + R * np.sin(t), 0.0, coarse) for t in angles]
        arcs = [geo.addCircleArc(pts[i], c, pts[(i + 1) % 5]) for i in range(5)]
        surf = geo.addPlaneSurface([geo.addCurveLoop(arcs)])
        geo.synchronize()
        gmsh.model.addPhysicalGroup(2, [surf], 1)
        gmsh.model.addPhysicalGroup(1, [arcs[0], arcs[4]], LOWER)
        gmsh.model.addPhysicalGroup(1, [arcs[1], arcs[3]], UPPER)
        gmsh.model.addPhysicalGroup(1, [arcs[2]], TOP)
        f = gmsh.model.mesh.field
        dist = f.add("Distance")
        f.setNumbers(dist, "PointsList", [pts[0]])
        thr = f.add("Threshold")
        f.setNumber(thr, "InField", dist)
        for k, v in (("SizeMin", h), ("SizeMax", coarse), ("DistMin", fine), ("DistMax", 3.0 * fine)):
            f.setNumber(thr, k, v)
        f.setAsBackgroundMesh(thr)
        for k, v in (("MeshSizeFromPoints", 0), ("MeshSizeFromCurvature", 0), ("MeshSizeExtendFromBoundary", 0),
                     ("Algorithm", 6), ("SecondOrderLinear", 0)):
            gmsh.option.setNumber(f"Mesh.{k}", v)
        gmsh.model.mesh.generate(2)
        gmsh.model.mesh.setOrder(2)
        msh, _, ft = compat.model_to_mesh(gmsh.model, comm, 0, gdim=2)
        gmsh.finalize() if owner else gmsh.model.remove()           # a caller's session left open
    else:
        msh, _, ft = compat.model_to_mesh(None, comm, 0, gdim=2)
    return msh, ft


def build(comm, R, E, nu, rho, depth, ramp, h, fine, coarse, arc):
    msh, ft = make_mesh(comm, R, h, fine, coarse, arc)
    fdim = msh.topology.dim - 1
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda u: ufl.sym(ufl.grad(u))                                        # noqa: E731
    sigma = lambda u: lmbda * ufl.tr(eps(u)) * ufl.Identity(2) + 2 * mu * eps(u)  # noqa: E731
    zero = fem.Constant(msh, np.zeros(2, dtype=PETSc.ScalarType))              # no body force
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=ft)(LOWER)
    top_facets = ft.indices[ft.values == TOP]
    punch = DirichletPart(
        "top", lambda m: top_facets,
        value=lambda x, t: np.array([[0.0], [-float(push(t, depth, ramp))]]),  # u = (0, -d(t)) on the arc
        components=None)                                                       # both: no rigid drift
    return Problem(
        name="punch", mesh=msh, shape=(2,), rho=rho, stress=sigma,
        a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx,
        l=lambda w: ufl.inner(zero, w) * ufl.dx,
        u0=lambda x: np.zeros((2, x.shape[1])), v0=lambda x: np.zeros((2, x.shape[1])),
        constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, lambda x: x[1] <= R * (1 + 1e-8)),
        lower_bound=lambda x: -x[1], constraint_component=1,                   # y + u_y >= 0
        constraint_measure=lambda q: q * ds_c,
        dirichlet_parts=[punch],
        probe=(0.0, 0.0), extra_columns=("contact_force", "elastic"),
        parameters={"lame_lambda": lmbda, "lame_mu": mu, "E_star": E / (1 - nu * nu),
                    "c_p": float(np.sqrt((lmbda + 2 * mu) / rho)),
                    "transit": float(2 * R / np.sqrt((lmbda + 2 * mu) / rho))},
        units={"t": "s", "E_star": "N/mm^2", "c_p": "mm/s", "transit": "s (2R / c_p)",
               "contact_force": "N per mm of thickness", "reaction_top_x": "N per mm of thickness",
               "reaction_top_y": "N per mm of thickness", "dirichlet_work": "N mm per mm of thickness",
               "elastic": "N mm per mm of thickness"})


PROBLEM = ProblemSpec(
    name="punch", build=build, doc=__doc__,
    params=(Param("R", 20.0, "radius of the disc", unit="mm", low=0.0, low_strict=True),
            Param("E", 1000.0, "Young's modulus", unit="N/mm^2", low=0.0, low_strict=True),
            Param("nu", 0.3, "Poisson's ratio", low=0.0, high=0.49),
            Param("rho", 1e-6, "density", unit="t/mm^3", low=0.0, low_strict=True),
            Param("depth", 0.6, "the push d of the top arc at the end of the ramp", unit="mm"),
            Param("ramp", 0.2, "duration of the ramp", unit="s", low=0.0, low_strict=True),
            Param("h", 0.125, "mesh size near the lowest point A", unit="mm", low=0.0, low_strict=True),
            Param("fine", 2.5, "radius of the zone of size h around A", unit="mm", low=0.0, low_strict=True),
            Param("coarse", 2.5, "mesh size far from A", unit="mm", low=0.0, low_strict=True),
            Param("arc", 15.0, "half-angle of the pushed top arc", unit="degrees", low=0.0, low_strict=True,
                  high=80.0)),
    defaults={"pair": "P1+/P0", "dt": 1e-3, "T": 0.2, "time_unit": "s"})
