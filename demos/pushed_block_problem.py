"""A block on a frictionless rigid foundation, its top pushed down by a prescribed displacement d(t).

The contact patch test with displacement control (a problem file: docs/add_a_problem.md). The
plane-strain rectangle [0, width] x [0, height] (nx x ny squares of two triangles) rests on the
foundation y = 0 (unilateral contact y + u_y >= 0 at its bottom vertices, frictionless); its top
face is a Dirichlet part ``top`` that prescribes u_y = -d(t) only, u_x free: a frictionless punch,
so that both faces slide and the block expands laterally without restraint. No gravity; it starts
unstressed at rest. The push is a smooth ramp held at the end,

    d(t) = push (1 - cos(pi t / ramp)) / 2  for t < ramp,   d(t) = push  afterwards,

which starts and ends at rest (d' = 0), slow against the block's vibrations (the slowest, the
column between the punch and the foundation, has omega_1 = pi c / height, c = sqrt(E / rho):
omega_1 ramp = 50 at the defaults), so the motion is quasi-static up to a residual vibration of
relative size ~ (pi / (omega_1 ramp))^2, which averaging over the hold removes.

Closed form (static, per mm of thickness). The homogeneous state of a uniaxial compression in y
with sigma_xx = 0 (free lateral faces, both loaded faces frictionless) and plane strain
(eps_zz = 0): with eps_yy = -d / height,

    sigma_xx = lambda eps_yy + (lambda + 2 mu) eps_xx = 0   =>   eps_xx = -lambda / (lambda + 2 mu) eps_yy,
    sigma_yy = (lambda + 2 mu) eps_yy + lambda eps_xx = 4 mu (lambda + mu) / (lambda + 2 mu) eps_yy
             = E / (1 - nu^2) eps_yy,

so the foundation carries, and the punch exerts, the force F = E / (1 - nu^2) width d / height
(E width d / height for nu = 0): the columns contact_force = +F and reaction_top_y = -F (the
support pushes the body down). The displacement u = (eps_xx (x - x0), eps_yy y) is linear: every
pair's W^h holds it, and it satisfies the vertex constraint (13) with equality at every bottom
node. Whether the discrete contact reproduces it depends on where the constraint acts: P1 and
P1+ (boundary dofs at vertices only) and P2 with --constrain nodes do; P2 with the constraint at
the vertices only cannot carry the uniform pressure at the mid-edge nodes, which sink between
the vertices (tests/physics/test_prescribed_motion.py measures it). :func:`force` evaluates F.
"""
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.problems import DirichletPart, Param, Problem, ProblemSpec


def force(E, nu, width, height, d):
    """F = E / (1 - nu^2) width d / height: the static force of the push d (plane strain, free sides)."""
    return E / (1.0 - nu * nu) * width * d / height


def push(t, depth, ramp):
    """d(t): the smooth ramp (1 - cos(pi t / ramp)) / 2 to ``depth``, then held."""
    s = np.clip(np.asarray(t, dtype=float) / ramp, 0.0, 1.0)
    return depth * 0.5 * (1.0 - np.cos(np.pi * s))


def push_rate(t, depth, ramp):
    """d'(t) (0 at t = 0 and after the ramp)."""
    t = float(t)
    return depth * 0.5 * np.pi / ramp * np.sin(np.pi * t / ramp) if 0.0 < t < ramp else 0.0


def build(comm, width, height, nx, ny, E, nu, rho, depth, ramp):
    msh = dmesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([width, height])], [nx, ny],
                                 dmesh.CellType.triangle)
    fdim = msh.topology.dim - 1
    tol = 1e-10 * height
    bottom = lambda x: np.abs(x[1]) <= tol                                      # noqa: E731
    top = lambda x: np.abs(x[1] - height) <= tol                                # noqa: E731
    facets = np.sort(dmesh.locate_entities_boundary(msh, fdim, bottom)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, fdim, facets, np.ones_like(facets)))(1)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda u: ufl.sym(ufl.grad(u))                                        # noqa: E731
    sigma = lambda u: lmbda * ufl.tr(eps(u)) * ufl.Identity(2) + 2 * mu * eps(u)  # noqa: E731
    zero = fem.Constant(msh, np.zeros(2, dtype=PETSc.ScalarType))              # no body force

    def strain_energy(C):
        """A hyperelastic psi(C) of this block (``--material problem``): compressible neo-Hookean, plane
        strain (C_33 = 1), written by hand; it linearises to a(u, w) below (the run checks it)."""
        lnJ = 0.5 * ufl.ln(ufl.det(C))
        return 0.5 * mu * (ufl.tr(C) - 2) - mu * lnJ + 0.5 * lmbda * lnJ ** 2
    punch = DirichletPart(
        "top", lambda m: dmesh.locate_entities_boundary(m, fdim, top),
        value=lambda x, t: -push(t, depth, ramp),                               # u_y = -d(t) on the top face
        velocity=lambda x, t: -push_rate(t, depth, ramp),
        components=(1,))                                                        # u_x free: frictionless
    return Problem(
        name="pushed_block", mesh=msh, shape=(2,), rho=rho, stress=sigma,
        a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx,
        l=lambda w: ufl.inner(zero, w) * ufl.dx,
        u0=lambda x: np.zeros((2, x.shape[1])), v0=lambda x: np.zeros((2, x.shape[1])),
        constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom),
        lower_bound=lambda x: -x[1], constraint_component=1,
        constraint_measure=lambda q: q * ds_c,
        dirichlet_parts=[punch], strain_energy=strain_energy,
        probe=(width / 2, 0.0), extra_columns=("contact_force",),
        parameters={"lame_lambda": lmbda, "lame_mu": mu, "force": force(E, nu, width, height, depth)},
        units={"t": "s", "force": "N per mm of thickness", "contact_force": "N per mm of thickness",
               "reaction_top_y": "N per mm of thickness", "dirichlet_work": "N mm per mm of thickness"})


PROBLEM = ProblemSpec(
    name="pushed_block", build=build, doc=__doc__,
    params=(Param("width", 20.0, "width", unit="mm", low=0.0, low_strict=True),
            Param("height", 10.0, "height", unit="mm", low=0.0, low_strict=True),
            Param("nx", 8, "squares along the width", type=int, low=1),
            Param("ny", 4, "squares along the height", type=int, low=1),
            Param("E", 1000.0, "Young's modulus", unit="N/mm^2", low=0.0, low_strict=True),
            Param("nu", 0.0, "Poisson's ratio", low=0.0, high=0.49),
            Param("rho", 1e-6, "density", unit="t/mm^3", low=0.0, low_strict=True),
            Param("depth", 0.01, "the push d held after the ramp", unit="mm"),
            Param("ramp", 5e-3, "duration of the ramp", unit="s", low=0.0, low_strict=True)),
    defaults={"pair": "P1+/P0", "dt": 1e-4, "T": 1e-2, "time_unit": "s"})
