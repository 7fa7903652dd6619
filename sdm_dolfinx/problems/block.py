"""A plane-strain elastic block sliding on the rigid foundation y = 0 (friction's closed forms).

The rectangle [0, width] x [0, height] (nx x ny squares, each cut into two triangles) rests on
the foundation: unilateral contact y + u_y >= 0 at its bottom vertices. Linear elasticity
(E, nu) in plane strain, density rho, gravity g downward, initial velocity (v0, 0) everywhere.
Units: mm, N, s, tonne as for the disc (stresses in N/mm^2, forces and momenta per mm of
thickness). By default it starts from its static equilibrium under gravity (--start
equilibrium), so that the foundation carries m g from t = 0 and no vertical oscillation is
excited; --start rest drops the unstressed block onto the foundation from zero height.

Closed forms (rigid block, m = rho width height per mm of thickness, L = width the contact
length): frictionless, it slides at v0 for ever and the normal force is m g. With Coulomb
friction mu the friction force is mu m g: the block decelerates at mu g and stops at
t* = v0 / (mu g) after v0^2 / (2 mu g). With a Tresca threshold s (a stress: s times each
bottom vertex's lumped length, s L in all) it decelerates at s L / m, stops at
t* = v0 m / (s L) after v0^2 m / (2 s L) (block.stopping).

Defaults: 20 x 10 mm, E = 1000 N/mm^2, nu = 0, rho = 1e-6 t/mm^3, g = 9810 mm/s^2, v0 = 100
mm/s: with mu = 0.3 it stops at t* = 34.0 ms after 1.70 mm; T = 0.04 s reaches the stop in 400
steps of dt = 1e-4 s, which resolves the block's slowest vibrations on the foundation (periods
1.4 to 2.4 ms, 14 to 24 steps: block.DT_NOTE). nu = 0 keeps the elastic block's Coulomb run on
its closed form: with nu >= 0.1 the Poisson effect couples slip and normal motion and a vertical
vibration grows (block.NU_NOTE).
"""
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.problems import base as _problem
from sdm_dolfinx.problems.base import Param, Problem, ProblemSpec

#: how the block starts: at its static equilibrium under gravity, or unstressed at rest on y = 0
STARTS = ("equilibrium", "rest")

#: why the default dt is 1e-4 s (measured on the default block, P2/P1: generalised eigenvalues of A
#: and M = B^T C^-1 B with the bottom vertices held in y, or in x and y)
DT_NOTE = ("dt = 1e-4 s resolves the default block's slowest vibrations on the foundation: periods 1.37 ms "
           "(the vertical mode, 99 % of the energy of a drop, --start rest), 1.59 ms (the mode a friction force "
           "on the bottom excites most while it slides) and 2.36 ms (the slowest while the bottom sticks): 14 "
           "to 24 steps a period, the midpoint scheme's period error (omega dt)^2/12 <= 1.8 %; the stop at "
           "mu = 0.3 (34 ms) takes 340 steps")

#: why the default Poisson's ratio is 0 (measured with Coulomb friction mu = 0.3, P2/P1, 400 steps)
NU_NOTE = ("nu = 0: the block's Poisson effect couples its slip to its normal motion, and with Coulomb friction "
           "(normal force -> friction -> shear -> normal displacement) a vertical vibration grows: nu = 0.3, "
           "dt = 1e-4 s: the contact force swings between 0 and 3.8 m g, the block lifts off, energy + "
           "dissipation rises 14 % (1.9 % at dt = 2.5e-5 s) and it has not stopped at 40 ms; nu = 0.1: 0.2 to "
           "2.1 m g, stops at 35.7 ms; nu = 0.05 and nu = 0: the closed form (velocity at 10, 20, 30 ms within "
           "0.05 mm/s, stop at 33.9 ms, contact force within 15 % and 6 % of m g). At nu = 0 a finer dt or "
           "mesh brings the vibration back (dt = 2.5e-5 s: 0.5 to 1.6 m g, stop at 36.2 ms); dt = 5e-5 to "
           "2e-4 s and E up to 1e5 N/mm^2 keep the closed form. Tresca friction (no normal coupling) follows "
           "its closed form at nu = 0.3 too")

#: the unit of every parameter and time-series column (for run.json; --help states them too)
UNITS = {"width": "mm", "height": "mm", "nx": "-", "ny": "-", "E": "N/mm^2", "nu": "-", "rho": "t/mm^3",
         "gravity": "mm/s^2 (downward)", "v0": "mm/s (horizontal, whole block)",
         "start": "- (equilibrium: static solution under gravity; rest: unstressed)",
         "lame_lambda": "N/mm^2 (plane strain)", "lame_mu": "N/mm^2", "mass": "t per mm of thickness",
         "probe": "mm (the bottom vertex nearest to the centre: u_probe and lambda_probe are recorded there)",
         "t": "s", "dt": "s", "T": "s",
         "energy": "N mm = mJ per mm of thickness (kinetic + elastic + gravity)", "kinetic": "N mm",
         "potential": "N mm (elastic energy minus the work of gravity)",
         "u_probe": "mm (vertical displacement of the probe)",
         "lambda_probe": "N/mm^2 (contact stress at the probe: nodal multiplier / lumped length; >= 0 compressive)",
         "contact_force": "N per mm of thickness (sum of the normal nodal multipliers; m g at equilibrium)",
         "momentum_x": "t mm/s = N s per mm of thickness (e_x^T M Vbar)",
         "momentum_y": "t mm/s = N s per mm of thickness (e_y^T M Vbar)",
         "elastic": "N mm (elastic strain energy 1/2 U^T A U)",
         "gap_min_boundary": "mm (min of y + u_y over every displacement dof of the bottom face, P2 mid-edge "
                             "nodes included)"}


def lame(E, nu):
    """Plane-strain Lamé parameters (lambda, mu) (N/mm^2) of Young's modulus E and Poisson's ratio nu."""
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def stopping(v0, gravity, mass, width, mu=None, threshold=None):
    """The rigid block's deceleration, stopping time and distance under friction (closed form).

    The block (mass m per mm of thickness) slides on y = 0 with every bottom point slipping in
    the same direction, so the friction force is the whole bound and opposes the motion:
    Coulomb, F = mu N with N = m g (vertical balance): deceleration a = mu g; Tresca, F = s L
    (the threshold s times the contact length L = width, whatever N): a = s L / m. A constant
    deceleration stops the block at t* = v0 / a after d = v0^2 / (2 a); afterwards it sticks
    (the static friction needed is 0 on a flat foundation).

    Args:
        v0: initial speed (mm/s). gravity: g (mm/s^2). mass: m (t per mm of thickness).
        width: the contact length L (mm). mu: Coulomb's coefficient, or threshold: Tresca's s
        (N/mm^2): exactly one of the two.

    Returns:
        ``(a, t_stop, distance)`` in mm/s^2, s, mm.
    """
    if (mu is None) == (threshold is None):
        raise ValueError("give exactly one of mu (Coulomb) and threshold (Tresca)")
    a = mu * gravity if mu is not None else threshold * width / mass
    v = abs(v0)
    return a, v / a, v * v / (2.0 * a)


def make_mesh(width, height, nx, ny, comm=MPI.COMM_WORLD):
    """The rectangle [0, width] x [0, height] cut into nx x ny squares of two triangles each."""
    return dmesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([width, height])], [nx, ny],
                                  dmesh.CellType.triangle)


def _on_bottom(height):
    """The predicate of the bottom face y = 0 (tolerance relative to the block's height)."""
    tol = 1e-10 * height
    return lambda x: np.abs(x[1]) <= tol


#: the displacement elements of the pairs (method/pairs.py), by their interpolation points per triangle
ELEMENTS_BY_POINTS = {3: ("Lagrange", 1), 4: ("P+", 1), 6: ("Lagrange", 2)}


def static_solution(msh, element, a, l, x_fixed, on_bottom, kind="vertices"):
    """The static displacement in ``element`` (a vector element) under the load: A u = L with
    u_y = 0 at the bottom vertices (``kind`` "nodes": at every bottom node, P2's mid-edge nodes
    too) and u_x = 0 at the bottom vertex x = ``x_fixed`` (which removes the rigid translation
    along x: the bottom is otherwise free to slide, the frictionless bilateral support).

    In the element of the run's W^h it is the discrete equilibrium: the foundation's nodal
    reactions A u - L sit at the y dofs where the run's constraint acts (the bottom vertices,
    eq. (13), or every bottom node), sum to m g, and a run started there stays there. Solved
    with a direct factorisation (MUMPS, any number of ranks).
    """
    V = compat.function_space(msh, element)
    verts = dmesh.locate_entities(msh, 0, on_bottom)
    held = (fem.locate_dofs_topological(V.sub(1), msh.topology.dim - 1,
                                        dmesh.locate_entities(msh, msh.topology.dim - 1, on_bottom))
            if kind == "nodes" else fem.locate_dofs_topological(V.sub(1), 0, verts))
    tol = 1e-10 * max(abs(x_fixed), 1.0)
    fixed = dmesh.locate_entities(msh, 0, lambda x: on_bottom(x) & (np.abs(x[0] - x_fixed) <= tol))
    zero = PETSc.ScalarType(0.0)
    bcs = [fem.dirichletbc(zero, held, V.sub(1)),
           fem.dirichletbc(zero, fem.locate_dofs_topological(V.sub(0), 0, fixed), V.sub(0))]
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    A = compat.assemble_matrix(compat.form(a(u, w)), bcs)
    b = compat.assemble_vector(compat.form(l(w)))
    compat.petsc_module().set_bc(b, bcs)          # homogeneous data: no lifting
    ksp = PETSc.KSP().create(msh.comm)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    us = fem.Function(V)
    ksp.solve(b, compat.petsc_vec(us))
    reason = ksp.getConvergedReason()
    ksp.destroy(), A.destroy(), b.destroy()
    if reason <= 0:
        raise RuntimeError(f"block: the static solve failed (KSP reason {reason})")
    us.x.scatter_forward()
    return us


class StaticStart:
    """u0 of ``--start equilibrium``: the static solution in the run's own W^h element.

    The Problem does not know the pair; ``Function.interpolate`` (the Discretisation's
    ``initial_state``) calls u0 with W^h's interpolation points of every local cell, cell by
    cell, whose number per cell names W^h's element among the pairs' (3: P1, 4: P1+, 6: P2).
    The static problem is solved in that element (once) and its values at the points returned,
    which W^h's interpolation reproduces exactly. (The P2 equilibrium interpolated into P1 or
    P1+ is no equilibrium there: the contact force then swings between 0.62 and 1.37 m g (P1),
    0.11 and 1.85 m g (P1+), measured.)
    Collective: every rank calls it, as ``Function.interpolate`` is.
    """

    def __init__(self, msh, solve, label="block --start equilibrium", instead="--start rest", kinds=("vertices",),
                 kind="vertices", general=()):
        """``solve(element, kind) -> fem.Function``: the static solution in a vector ``element`` with
        the constraint of ``kind`` (one of ``kinds``: "vertices", "nodes"); ``label`` and ``instead``
        name the option and its alternative in the error message; ``general``: the kinds whose start is
        the run's own static solve (:data:`~sdm_dolfinx.problems.base.EQUILIBRIUM`, e.g. "weighted")."""
        self.msh, self.solve, self.label, self.instead, self.kinds, self.kind = msh, solve, label, instead, kinds, kind
        self.general = general
        self.solutions = {}

    def for_constraint(self, kind):
        """The start for the run's constraint kind (the Discretisation asks): the equilibrium with the
        constraint held where that kind holds it (ProblemInputError for a kind it cannot solve), or
        :data:`~sdm_dolfinx.problems.base.EQUILIBRIUM` for the ``general`` kinds."""
        if kind in self.general:
            return _problem.EQUILIBRIUM
        if kind == self.kind:
            return self
        if kind not in self.kinds:
            where = {"vertices": "at every vertex", "nodes": "at every node",
                     "weighted": "as the weighted gap"}.get(kind, f"of kind {kind}")
            raise _problem.ProblemInputError(f"{self.label}: no static solution with the constraint {where} "
                                             f"(constrain {kind}); use {self.instead}")
        return StaticStart(self.msh, self.solve, self.label, self.instead, self.kinds, kind, self.general)

    def __call__(self, x):
        msh = self.msh
        imap = msh.topology.index_map(msh.topology.dim)
        ncells = imap.size_local + imap.num_ghosts
        ppc = msh.comm.allreduce(x.shape[1] // ncells if ncells else 0, op=MPI.MAX)
        if ppc not in ELEMENTS_BY_POINTS or x.shape[1] != ppc * ncells:
            raise _problem.ProblemInputError(
                f"{self.label}: no static solution for a displacement element with {ppc} "
                f"interpolation points per cell (P1, P1+ and P2 have one); use {self.instead}")
        if ppc not in self.solutions:
            family, degree = ELEMENTS_BY_POINTS[ppc]
            cell = compat.cell_name(msh)
            element = (compat.p1_bubble_element(cell, (2,)) if family == "P+"
                       else compat.element(family, cell, degree, (2,)))
            self.solutions[ppc] = self.solve(element, self.kind)
        cells = np.repeat(np.arange(ncells, dtype=np.int32), ppc)
        return self.solutions[ppc].eval(np.ascontiguousarray(x.T), cells).T


def _build(comm, width, height, nx, ny, E, nu, rho, gravity, v0, start):
    """The block Problem for declared values (see :data:`SPEC`).

    Frictionless, the equilibrium start is exact: with U^0 = U_s (the static solution in W^h,
    :class:`StaticStart`) and Vbar^0 = v0 e_x, U^n = U_s + v0 t_n e_x solves the midpoint scheme
    (A e_x = 0, so A U^{n+1/2} = A U_s), with the multipliers lam = A U_s - L >= 0 at every
    bottom vertex, whose sum is -e_y^T L = m g: the foundation carries m g at every step and the
    block keeps its momentum m v0. The default dt: :data:`DT_NOTE`.
    """
    msh = make_mesh(width, height, nx, ny, comm)
    fdim = msh.topology.dim - 1
    on_bottom = _on_bottom(height)
    facets = np.sort(dmesh.locate_entities(msh, fdim, on_bottom)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, fdim, facets, np.ones_like(facets)))(1)
    lmbda, mu = lame(E, nu)
    # a Constant, not a literal vector: with gravity = 0 UFL would simplify the load to an empty form
    g = fem.Constant(msh, np.array((0.0, -gravity), dtype=PETSc.ScalarType))

    def sigma(u):
        """Plane-strain Hooke's law: sigma = lambda tr(eps) I + 2 mu eps (the Problem's ``stress``)."""
        eps_u = ufl.sym(ufl.grad(u))
        return lmbda * ufl.tr(eps_u) * ufl.Identity(2) + 2.0 * mu * eps_u

    def a(u, w):
        """Plane-strain elasticity: (sigma(u), eps(w))."""
        return ufl.inner(sigma(u), ufl.sym(ufl.grad(w))) * ufl.dx

    def l(w):                                                                # noqa: E741 (the paper's L)
        """Gravity: (rho g, w)."""
        return rho * ufl.inner(g, w) * ufl.dx

    x_probe = (nx // 2) * width / nx                 # the bottom vertex nearest to the centre
    if start == "equilibrium":
        u0 = StaticStart(msh, lambda element, kind: static_solution(msh, element, a, l, x_probe, on_bottom, kind),
                         kinds=("vertices", "nodes"), general=("weighted",))
    else:
        u0 = lambda x: np.zeros((2, x.shape[1]))                             # noqa: E731
    return _problem.Problem(
        name="block", mesh=msh, shape=(2,), rho=rho, a=a, l=l, u0=u0, stress=sigma,
        v0=lambda x: np.vstack([np.full(x.shape[1], v0), np.zeros(x.shape[1])]),
        constraint_vertices=lambda m: dmesh.locate_entities(m, 0, on_bottom),
        # the foundation y = 0: a vertex at height y keeps y + u_y >= 0
        lower_bound=lambda x: -x[1],
        constraint_component=1,
        # lumped length of the bottom face at each vertex: stress = lambda_i / |Gamma_i|
        constraint_measure=lambda q: q * ds_c,
        probe=(x_probe, 0.0),
        extra_columns=("contact_force", "momentum_x", "momentum_y", "elastic"),
        momentum_component=1,
        parameters={"width": width, "height": height, "nx": nx, "ny": ny, "E": E, "nu": nu, "rho": rho,
                    "gravity": gravity, "v0": v0, "start": start, "lame_lambda": lmbda, "lame_mu": mu,
                    "mass": rho * width * height, "plane": "strain", "diagonal": "right",
                    "probe": f"bottom vertex ({x_probe:.10g}, 0)"},
        units=dict(UNITS),
    )


#: the block's parameters, declared once (command line, TOML, run.json, rebuild)
PARAMS = (
    Param("width", 20.0, "width of the block (its contact length)", unit="mm", low=0.0, low_strict=True),
    Param("height", 10.0, "height of the block", unit="mm", low=0.0, low_strict=True),
    Param("nx", 10, "squares along the width (two triangles each)", type=int, low=1),
    Param("ny", 5, "squares along the height", type=int, low=1),
    Param("E", 1000.0, "Young's modulus", unit="N/mm^2", low=0.0, low_strict=True),
    Param("nu", 0.0, "Poisson's ratio (0: the block's slip does not move it normally: with Coulomb friction and "
          "nu >= 0.1 a vertical vibration grows, see block.NU_NOTE)", low=-1.0, low_strict=True, high=0.49),
    Param("rho", 1e-6, "density (1000 kg/m^3)", unit="t/mm^3", low=0.0, low_strict=True),
    Param("gravity", 9810.0, "gravitational acceleration (downward)", unit="mm/s^2", low=0.0),
    Param("v0", 100.0, "initial horizontal velocity of the block", unit="mm/s"),
    Param("start", "equilibrium", "initial state: the static equilibrium under gravity (the foundation carries m g "
          "from t = 0) or the unstressed block at rest on y = 0 (it then vibrates vertically)", type=str,
          choices=STARTS),
)


def estimate(values):
    """The mesh the parameter ``values`` make, counted without building it (for the memory
    estimate of a run): vertices, edges and triangles of the nx x ny rectangle."""
    nx, ny = values["nx"], values["ny"]
    vertices, cells = (nx + 1) * (ny + 1), 2 * nx * ny
    return {"vertices": vertices, "edges": vertices + cells - 1,   # Euler: V - E + F = 1
            "cells": cells, "value_size": 2, "by": ("nx", "ny")}


SPEC = ProblemSpec(
    name="block", build=_build, params=PARAMS, estimate=estimate, doc=(__doc__ or "").strip(),
    defaults={"pair": "P2/P1", "scheme": "midpoint", "dt": 1e-4, "T": 0.04, "time_unit": "s"},
)


def problem(comm: MPI.Comm = MPI.COMM_WORLD, **values: Any) -> Problem:
    """The sliding block; ``values`` are :data:`PARAMS` (``width``, ``height``, ``nx``, ``ny``,
    ``E``, ``nu``, ``rho``, ``gravity``, ``v0``, ``start``), the others at their defaults."""
    return SPEC.problem(comm, **values)


def total_mass(problem):
    """rho |Omega| of the mesh (t per mm of thickness): the discrete mass e^T M e."""
    m = fem.assemble_scalar(compat.form(problem.rho * ufl.dx(domain=problem.mesh)))
    return problem.mesh.comm.allreduce(m, op=MPI.SUM)
