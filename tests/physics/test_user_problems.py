"""Silent wrong results in a user's own problem (Reliability II, item 10), each against a closed
form or an independent computation, on the plane-strain block of docs/add_a_problem.md:

* a time-dependent load (``Problem.time``) is reassembled every step at the scheme's load time
  (midpoint: t_{n+1/2}, backward Euler: t_{n+1}): a rigid translation under a load switched on
  or flipped matches its closed form to round-off; an elastic block matches the exact solution
  of the semi-discrete problem (modal, from the same matrices) with order 2; a load Constant
  changed during a run without ``time`` stops the run naming it;
* a vector problem must name its constrained component;
* every dof of W^h on the constrained boundary (P2 mid-edge nodes) is watched (gap_min_boundary);
* an initial state below the bound and a pair without element on tetrahedra are refused;
* ``disc --mesh`` of a disc whose lowest point is not a node probes its lowest vertex.
1 and 2 ranks.
"""
import json
import re

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.errors import StepError
from sdm_dolfinx.problems import Problem, ProblemInputError, membrane
from sdm_dolfinx.run import simulate

COMM = MPI.COMM_WORLD


def block(comm=COMM, width=20.0, height=10.0, gap=0.5, E=1000.0, nu=0.3, rho=1e-6, v0=-500.0, n=10, floor=True,
          load=None, time=None, clamp_top=False, component=1):
    """The block of docs/add_a_problem.md; ``load(msh)`` -> the body force (a UFL vector; default
    gravity), ``time(msh)`` -> the Problem's time Constant, ``clamp_top``: u = 0 on the top face."""
    msh = dmesh.create_rectangle(comm, [np.array([0.0, gap]), np.array([width, gap + height])],
                                 [n, max(1, round(n * height / width))], dmesh.CellType.triangle)
    fdim = msh.topology.dim - 1
    bottom = lambda x: np.isclose(x[1], gap)
    top = lambda x: np.isclose(x[1], gap + height)
    facets = np.sort(dmesh.locate_entities_boundary(msh, fdim, bottom)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, fdim, facets, np.ones_like(facets)))(1)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda u: ufl.sym(ufl.grad(u))
    sigma = lambda u: lmbda * ufl.tr(eps(u)) * ufl.Identity(2) + 2 * mu * eps(u)
    t = time(msh) if time is not None else None
    g = load(msh, t) if load is not None else fem.Constant(msh, PETSc.ScalarType((0.0, -9810.0)))

    def top_facets(m):
        m.topology.create_connectivity(fdim, fdim + 1)
        return dmesh.locate_entities_boundary(m, fdim, top)

    return Problem(
        name="block", mesh=msh, shape=(2,), rho=rho,
        a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx,
        l=lambda w: rho * ufl.inner(g, w) * ufl.dx,
        u0=lambda x: np.zeros((2, x.shape[1])),
        v0=lambda x: np.vstack([np.zeros(x.shape[1]), np.full(x.shape[1], v0)]),
        constraint_vertices=(lambda m: dmesh.locate_entities_boundary(m, 0, bottom)) if floor
        else (lambda m: np.zeros(0, dtype=np.int32)),
        lower_bound=lambda x: -x[1], constraint_component=component,
        constraint_measure=lambda q: q * ds_c,
        dirichlet_facets=top_facets if clamp_top else None,
        dirichlet_value=(lambda x: np.zeros((2, x.shape[1]))) if clamp_top else None,
        probe=(width / 2, gap), extra_columns=("contact_force", "momentum_y"),
        parameters={"lame_lambda": lmbda, "lame_mu": mu}, **({"time": t} if t is not None else {}))


def step_load(t1, f0):
    """A vertical body force f0 switched on at t = t1 (a function of the time Constant)."""
    return lambda msh, t: ufl.as_vector((0.0, ufl.conditional(ufl.ge(t, t1), f0, 0.0)))


def time_constant(msh):
    return fem.Constant(msh, PETSc.ScalarType(0.0))


# ------------------------------------------------------------------ a. time-dependent loads
#: the rigid translation under the ramp f(t) = F t of each scheme, from its recursion (exact):
#: midpoint, L(t_{n+1/2}): V^{n+1} = V^n + dt F t_{n+1/2}, U^{n+1} = U^n + dt (V^n + V^{n+1}) / 2;
#: backward Euler, L(t_{n+1}): V^{n+1} = V^n + dt F t_{n+1}, U^{n+1} = U^n + dt V^{n+1}
RAMP = {"midpoint": (lambda t, dt: t ** 3 / 6 + t * dt ** 2 / 12, lambda t, dt: t ** 2 / 2),
        "backward-euler": (lambda t, dt: t * (t + dt) * (t + 2 * dt) / 6, lambda t, dt: t * (t + dt) / 2)}


@pytest.mark.parametrize("scheme", sorted(RAMP))
def test_ramp_load_on_a_free_block_is_the_schemes_rigid_translation(scheme):
    """No floor, at rest, body force F t (F = 0.6): every point moves by the same u_y, which each
    scheme's recursion gives in closed form (RAMP); a load evaluated at another time (t_n, or
    t_{n+1} for the midpoint) differs at O(dt^2), the load assembled once gives u = 0."""
    dt, F = 0.01, 0.6
    p = block(floor=False, v0=0.0, load=lambda msh, t: ufl.as_vector((0.0, F * t)), time=time_constant)
    r = simulate(p, pair="P2/P1", scheme=scheme, dt=dt, T=0.3)
    t = r.timeseries["t"]
    u, v = (F * f(t, dt) for f in RAMP[scheme])
    assert np.max(np.abs(r.timeseries["u_probe"] - u)) <= 1e-7 * np.max(u)     # the step solves: rtol ~1e-9
    mass = p.rho * 20.0 * 10.0
    assert np.max(np.abs(r.timeseries["momentum_y"] - mass * v)) <= 1e-7 * mass * np.max(v)


def flipped_load(dt):
    """(load, on_step): a load Constant (0, -0.6) that ``on_step`` flips to (0, +0.6) after the
    step reaching t = 0.2."""
    box = {}

    def load(msh, t):
        box["c"] = fem.Constant(msh, PETSc.ScalarType((0.0, -0.6)))
        return box["c"]

    def flip(step, row):
        if abs(step * dt - 0.2) < 1e-9:
            box["c"].value = (0.0, 0.6)
    return load, flip


def test_load_flipped_in_on_step_is_used_with_time_declared():
    """The load Constant flipped from -0.6 to +0.6 after the step reaching t = 0.2 (on_step): with
    ``time`` declared L is reassembled every step, so the block moves as its closed form
    u = -0.3 t^2 until 0.2, then u(0.2) + v(0.2) s + 0.3 s^2 (s = t - 0.2), exactly."""
    dt = 0.01
    load, flip = flipped_load(dt)

    r = simulate(block(floor=False, v0=0.0, load=load, time=time_constant), pair="P2/P1", dt=dt, T=0.4,
                 on_step=flip)
    t = r.timeseries["t"]
    s = np.maximum(t - 0.2, 0.0)
    exact = np.where(t <= 0.2 + 1e-12, -0.3 * t ** 2, -0.3 * 0.04 - 0.12 * s + 0.3 * s ** 2)
    assert np.max(np.abs(r.timeseries["u_probe"] - exact)) <= 1e-7 * np.max(np.abs(exact))


def test_load_constant_changed_without_time_stops_the_run():
    """The same flip without ``time``: L was assembled once and the flip would have no effect at
    all (the run equal to the constant-load run to the last digit); the run stops at the next
    step naming the Constant and both values."""
    dt = 0.01
    load, flip = flipped_load(dt)

    with pytest.raises(StepError) as e:
        simulate(block(floor=False, v0=0.0, load=load), pair="P2/P1", dt=dt, T=0.4, on_step=flip)
    msg = str(e.value)
    assert msg.startswith("step 21 (t = 0.21): the Constant c_") and "of l(w)" in msg, msg
    assert "from (0, -0.6) to (0, 0.6)" in msg and "Problem(time=t)" in msg and "\n" not in msg, msg


def _semi_discrete_probe(t1, f0, times):
    """u_y at the probe of the exact solution of M U'' + A U = H(t - t1) L0, U(0) = U'(0) = 0, for
    the clamped P1/P1 block (M SPD): U = sum_k phi_k l_k (1 - cos(w_k (t - t1))) with A phi = w^2 M phi,
    phi^T M phi = 1, l_k = phi_k^T L0 / w_k^2. Built on COMM_SELF (every rank the same numbers)."""
    import scipy.linalg
    import scipy.sparse
    p = block(comm=MPI.COMM_SELF, floor=False, v0=0.0, E=1.0, rho=1.0, width=2.0, height=1.0, n=4, clamp_top=True,
              load=lambda msh, t: ufl.as_vector((0.0, f0)))
    d = Discretisation(p, "P1/P1")
    dense = lambda Mat: scipy.sparse.csr_matrix(Mat.getValuesCSR()[::-1], shape=Mat.getSize()).toarray()
    free = np.setdiff1d(np.arange(d.A.getSize()[0]), d.ddofs)
    A, M, L0 = dense(d.A)[np.ix_(free, free)], dense(d.M)[np.ix_(free, free)], d.L.array[free]
    w2, phi = scipy.linalg.eigh(A, M)
    lk = phi.T @ L0 / w2
    u = fem.Function(d.W)
    cells = compat.colliding_cells(p.mesh, compat.bounding_box_tree(p.mesh), np.array([[1.0, 0.5, 0.0]])).links(0)
    out = []
    for t in times:
        U = np.zeros(d.A.getSize()[0])
        U[free] = phi @ (lk * (1.0 - np.cos(np.sqrt(w2) * max(t - t1, 0.0))))
        u.x.array[:] = U
        out.append(u.eval(np.array([[1.0, 0.5, 0.0]]), cells[:1])[1])
    return np.array(out)


def test_step_load_on_a_clamped_block_converges_to_the_semi_discrete_solution():
    """The elastic block clamped at the top, load f0 = -1 switched on at t1 = 0.1 (a step
    boundary): the midpoint scheme with L(t_{n+1/2}) converges to the semi-discrete solution with
    order 2 in dt (relative errors 3.3e-4, 8.3e-5, 2.1e-5; L at t_{n+1} switches it on a step early:
    order 1. L at t_n coincides here: the ramp test above tells it apart)."""
    t1, f0, T = 0.1, -1.0, 1.0
    errors = []
    for dt in (0.02, 0.01, 0.005):
        p = block(floor=False, v0=0.0, E=1.0, rho=1.0, width=2.0, height=1.0, n=4, clamp_top=True,
                  load=step_load(t1, f0), time=time_constant)
        r = simulate(p, pair="P1/P1", dt=dt, T=T)
        exact = _semi_discrete_probe(t1, f0, r.timeseries["t"])
        errors.append(np.max(np.abs(r.timeseries["u_probe"] - exact)) / np.max(np.abs(exact)))
    slope = np.polyfit(np.log([0.02, 0.01, 0.005]), np.log(errors), 1)[0]
    assert errors[-1] < 2e-3 and slope > 1.8, (errors, slope)


def test_scheme_without_load_time_refuses_a_time_dependent_load():
    from sdm_dolfinx import schemes
    from sdm_dolfinx.run.integrator import Integrator
    from sdm_dolfinx.schemes.midpoint import Midpoint

    class Anonymous(Midpoint):
        name, load_theta = "anonymous-midpoint", None

    schemes.register(Anonymous())
    try:
        d = Discretisation(block(floor=False, n=2, load=step_load(0.1, 1.0), time=time_constant), "P1/P1")
        with pytest.raises(DiscretisationError, match="does not say when it evaluates"):
            Integrator(d, "anonymous-midpoint", 1e-3)
    finally:
        schemes._REGISTRY.pop("anonymous-midpoint")


def test_dirichlet_value_changed_during_the_run_stops_it():
    """dirichlet_value is evaluated once: one that changes is refused (moving data are Dirichlet parts,
    tests/physics/test_prescribed_motion.py)."""
    box = {"g": 0.0}
    p = block(floor=False, v0=0.0, n=2, clamp_top=True)
    p.dirichlet_value = lambda x: np.vstack([np.zeros(x.shape[1]), np.full(x.shape[1], box["g"])])

    def move(step, row):
        box["g"] = 0.1 if step >= 3 else 0.0

    with pytest.raises(StepError, match=r"step 4 .*dirichlet_value\(x\) on the Dirichlet boundary changed.*not "
                                        r"supported"):
        simulate(p, pair="P1/P1", dt=1e-5, T=1e-4, on_step=move)


# ------------------------------------------------------------------ b. constrained component
def test_vector_problem_must_name_its_constrained_component():
    with pytest.raises(ProblemInputError, match=r"^problem 'block': a vector problem must name constraint_component"):
        block(component=None, n=2)
    with pytest.raises(ProblemInputError, match=r"integer in 0\.\.1 .*got 2"):
        block(component=2, n=2)
    p = block(n=2)
    p.constraint_component = None                      # changed after construction: the Discretisation checks
    with pytest.raises(ProblemInputError, match="must name constraint_component"):
        Discretisation(p, "P2/P1")


# ------------------------------------------------------------------ e. the constrained boundary's dofs
def test_p2_mid_edge_nodes_sink_below_the_floor_and_are_reported():
    """Block, h = 2 mm, P2/P1, dt = 2e-5: at step 73 the vertices of the bottom face are within
    v dt of the floor but the mid-edge nodes are ~0.04 mm below it. gap_min_boundary equals an
    independent evaluation of y + u_y at the bottom face's nodes; one warning (rank 0), one line."""
    import warnings
    from sdm_dolfinx.run.result import BoundaryGapWarning
    dt = 2e-5
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = simulate(block(), pair="P2/P1", dt=dt, T=73 * dt)
    gmin = r.timeseries["gap_min_boundary"]
    assert gmin[-1] < -0.03 and r.gap_end.min() > -500.0 * dt
    u = r.displacement()
    msh = r.discretisation.problem.mesh
    x = np.zeros((21, 3))
    x[:, 0], x[:, 1] = np.arange(21.0), 0.5                  # vertices (even) and mid-edge nodes (odd)
    cells = compat.colliding_cells(msh, compat.bounding_box_tree(msh), x)
    nowned = msh.topology.index_map(2).size_local
    local = [i for i in range(21) if len([c for c in cells.links(i) if c < nowned])]
    vals = np.full(21, np.inf)
    if local:
        vals[local] = u.eval(x[local], [[c for c in cells.links(i) if c < nowned][0] for i in local])[:, 1] + 0.5
    vals = np.minimum.reduce(COMM.allgather(vals))
    assert abs(vals.min() - gmin[-1]) < 1e-12 and vals[1::2].min() < vals[0::2].min() - 0.03
    mine = [str(w.message) for w in caught if issubclass(w.category, BoundaryGapWarning)]
    assert len(mine) == (1 if COMM.rank == 0 else 0), mine
    if mine:
        assert "below its constrained vertices at (" in mine[0] and "eq. (13)" in mine[0] and "\n" not in mine[0]
        line = warnings.formatwarning(mine[0], BoundaryGapWarning, "sdm_dolfinx", 0)
        assert line.startswith("sdm_dolfinx:0: BoundaryGapWarning: step ") and line.count("\n") == 1


def test_a_sink_small_against_the_body_but_large_against_its_motion_is_reported():
    """The built-in block (20 x 10 mm, E = 1000, nu = 0, rho g = 9.81e-3 N/mm^3) resting at its static
    equilibrium, P2/P1 with the vertex constraint: its weight shortens it by rho g H^2 / (2 E) = 4.9e-4 mm
    (a bar under its own weight), and the foundation's mid-edge nodes sink between the constrained
    vertices by a sizeable part of that (measured 1.4e-4 mm). Far below the 1e-3 x diameter (0.02 mm)
    tolerance the warning used alone, so it was silent: the warning (at the end of the run) now compares
    the deepest sink with the run's own displacement spread (here the weight's shortening), says it (the
    vertices are at the foundation, so the sink is -gap_min_boundary) and names the option that holds the
    face; with constrain='nodes' every node of the face is at the foundation (to round-off of the
    displacements, 1e-12 of the shortening) and nothing is reported."""
    import warnings
    from sdm_dolfinx.problems.registry import get
    from sdm_dolfinx.run.result import BOUNDARY_SINK_RTOL, BoundaryGapWarning
    rho, g, H, E = 1e-6, 9810.0, 10.0, 1000.0
    shortening = rho * g * H ** 2 / (2 * E)
    found = {}
    for constrain in ("vertices", "nodes"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            r = simulate(get("block").problem(v0=0.0), pair="P2/P1", dt=1e-4, T=2e-4, constrain=constrain)
        found[constrain] = ([str(w.message) for w in caught if issubclass(w.category, BoundaryGapWarning)],
                            r.timeseries["gap_min_boundary"])
    mine, gap = found["vertices"]
    sink = -gap.min()
    assert BOUNDARY_SINK_RTOL * shortening < sink < 1e-3 * 20.0, (sink, shortening)
    assert len(mine) == (1 if COMM.rank == 0 else 0), mine
    if mine:
        said = float(re.search(r"sank ([0-9.e+-]+) below", mine[0]).group(1))  # printed to 3 digits
        assert abs(said - sink) <= 5e-3 * sink and "constrain='nodes'" in mine[0] and "\n" not in mine[0]
    mine, gap = found["nodes"]
    assert not mine and gap.min() > -1e-12 * shortening


def test_p1_bubble_boundary_gap_is_the_vertex_gap():
    """P1+/P0: on a boundary facet the bubble vanishes, so the boundary dofs are the vertices: the
    column equals the vertex gap of every step, and nothing is reported."""
    dt = 2e-5
    r = simulate(block(n=5), pair="P1+/P0", dt=dt, T=60 * dt)
    np.testing.assert_allclose(r.timeseries["gap_min_boundary"][1:], r.gap_end, rtol=0, atol=1e-14)  # round-off


# ------------------------------------------------------------------ f. initial state
def test_initial_state_below_the_obstacle_is_refused():
    with pytest.raises(DiscretisationError) as e:
        simulate(membrane.problem(N=10, obstacle=0.05), pair="P1+/P0", dt=1e-3, T=0.01)
    msg = str(e.value)
    assert msg.startswith("problem 'membrane': the initial displacement is below the bound at 81 constrained "
                          "vertices, by up to 0.03 at (") and "\n" not in msg, msg
    assert isinstance(e.value, ProblemInputError)           # the command line: exit status 2
    # at the obstacle exactly is fine
    simulate(membrane.problem(N=4, obstacle=0.02), pair="P1+/P0", dt=1e-3, T=0.002)


# ------------------------------------------------------------------ d. pairs on tetrahedra
def test_bubble_pair_on_tetrahedra_has_one_bubble_per_cell():
    msh = dmesh.create_unit_cube(COMM, 2, 2, 2)
    p = Problem(name="cube", mesh=msh, shape=(), a=lambda u, w: ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx,
                l=lambda w: -0.6 * w * ufl.dx, u0=lambda x: np.zeros(x.shape[1]), v0=lambda x: np.zeros(x.shape[1]),
                constraint_vertices=lambda m: np.zeros(0, dtype=np.int32), lower_bound=lambda x: np.zeros(x.shape[1]),
                constraint_measure=lambda q: q * ufl.dx, probe=(0.5, 0.5, 0.5))
    # P1 + the quartic bubble (basix has no cubic one on a tetrahedron): 27 vertices + 48 cells
    # (2^3 cubes x 6 tetrahedra); P0: one per cell, P1: one per vertex
    assert (Discretisation(p, "P1+/P0").dims()["dim_W"], Discretisation(p, "P1+/P0").dims()["dim_H"]) == (75, 48)
    assert Discretisation(p, "P1+/P1").dims()["dim_H"] == 27
    assert Discretisation(p, "P2/P1").dims()["dim_W"] == 125


# ------------------------------------------------------------------ c. disc --mesh, lowest point not a node
def _polygon_disc(path, n=48, radius=20.0, centre=(0.0, 30.0), h=4.0):
    """A P1 gmsh mesh of the n-gon inscribed in the disc, rotated by half a side: its lowest
    points are a horizontal edge's ends, not (0, centre_y - radius)."""
    import gmsh
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("polygon")
    geo = gmsh.model.geo
    angles = -np.pi / 2 + np.pi / n + 2 * np.pi * np.arange(n) / n
    pts = [geo.addPoint(centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a), 0.0, h) for a in angles]
    lines = [geo.addLine(pts[i], pts[(i + 1) % n]) for i in range(n)]
    surf = geo.addPlaneSurface([geo.addCurveLoop(lines)])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [surf], 1)
    gmsh.model.mesh.generate(2)
    gmsh.write(str(path))
    gmsh.finalize()
    return centre[1] - radius * np.cos(np.pi / n), radius * np.sin(np.pi / n)


def test_disc_mesh_without_a_node_at_the_lowest_point_probes_its_lowest_vertex(mpi_tmp_path):
    from sdm_dolfinx import cli
    path = mpi_tmp_path / "polygon.msh"
    y0, half = _polygon_disc(path) if COMM.rank == 0 else (None, None)
    y0, half = COMM.bcast((y0, half), root=0)
    out = mpi_tmp_path / "run"
    assert cli.main(["disc", "--mesh", str(path), "--dt", "1e-4", "--T", "5e-4", "--out", str(out), "--quiet"]) == 0
    if COMM.rank == 0:
        info = json.loads((out / "run.json").read_text())
        probe = info["problem"]["probe"]
        assert abs(probe[1] - y0) < 1e-9 and abs(abs(probe[0]) - half) < 1e-9, probe
        assert info["problem"]["parameters"]["probe"].startswith("lowest boundary vertex (")


@pytest.mark.parametrize("which", ["l", "a"])
def test_a_python_number_changed_during_the_run_is_refused(which):
    """A load (or stiffness) read from a plain Python number and changed in on_step stops the run at the
    next step, naming the form: it was ignored (the run bit-identical to the unchanged one), although the
    docs promise never a silently ignored load. Unchanged, the watched run is the unwatched run."""
    import ufl
    from sdm_dolfinx.problems import membrane
    box = {"f": -0.6, "k": 1.0}
    p = membrane.problem(N=6)
    a0, l0 = p.a, p.l
    p.l = lambda w: box["f"] * w * ufl.dx if which == "l" else l0(w)
    p.a = (lambda u, w: box["k"] * a0(u, w)) if which == "a" else a0
    ref = simulate(membrane.problem(N=6), T=0.1).timeseries["energy"]
    watched = simulate(p, T=0.1, on_step=lambda n, row: None).timeseries["energy"]
    assert np.array_equal(ref, watched)

    def change(n, row):
        if n == 30:
            box["f" if which == "l" else "k"] *= 2.0
    with pytest.raises(StepError, match=rf"step 31 .*a Python number read by {which}\("):
        simulate(p, T=0.1, on_step=change)
