"""Rigid obstacles as signed distances (``Problem.obstacles``): gap rows G U >= g, closed forms.

* **A plane is the old bound.** The paper's disc with its foundation y + u_y >= 0 declared as
  ``HalfSpace((0, 0), (0, 1))`` instead of ``lower_bound = -y``: each row is n . X_i >= n . U^n_i -
  phi(a_i + U^n_i) = U^n_y - (y_i + U^n_y) = -y_i, the same bound; the gap-row solver then does the
  dense Schur complement's arithmetic on the same numbers (a zero coefficient reads no column), so
  the histories agree to round-off: asserted 1e-12 of each column's scale on 1 rank (measured 0), 1e-10
  on more (two runs on several ranks differ at round-off: the parallel factorisation is not
  bit-reproducible from run to run; measured 4e-12 on 3 ranks).
* **An inclined plane is tilted gravity (rotation invariance).** A block on the plane through 0
  with normal n = (-sin t, cos t), mesh rotated by t, vertical gravity, against the same block
  axis-aligned on y >= 0 with gravity rotated by -t: the discrete problems are the same up to the
  rotation R (A_rot = R A R^T node-wise, M likewise, L_rot = R L, the rows n . u_i = e_y . R^T u_i),
  so energies and contact forces agree and the momenta are rotated, up to the step solver's
  tolerance and round-off: asserted 1e-9 of their scale (measured 2e-12), the gaps within 1e-11 W
  (the rotated coordinates' round-off: measured 2e-14 mm). And, exactly in the
  discrete scheme, the contact forces lam_i n_i have no component along the slope s = (cos t,
  sin t) while e_s is a rigid translation (A e_s = 0): the momentum along the slope is
  p_s(t_n) = -m g sin(t) t_n (the midpoint momentum balance, frictionless), asserted within 1e-10
  of m g t (measured 4e-13): a force with a tangential part (a normal taken at the wrong place)
  breaks it.
* **A disc in a circular bowl (demos/bowl_problem.py)**: frictionless, the disc translates and its
  centre moves on the circle of radius L = Rb - r: a pendulum of period T0 = 2 pi sqrt(L / g) for
  small angles (theta0 = 11.5 degrees: the finite-amplitude correction 1 + theta0^2 / 16 is
  +0.25 %). Measured from the zero crossings of the momentum along x: within 0.1 % of T0 (r = 10,
  Rb = 40 mm, dt = T0 / 2000); asserted within 1 %. The curved obstacle's rows are linearised at
  the current configuration every step: with the normal of the starting position kept instead,
  there would be no restoring force at all.
* **A plane moving along its normal is the moving bound.** The block on a floor rising as s(t):
  ``HalfSpace((0, 0), (0, 1), motion=t -> (0, s(t)))`` imposes, with the midpoint scheme's weight
  1/2, n . X >= U^n_y - (phi(t_n) + phi(t_{n+1}))/2 = (s(t_n) + s(t_{n+1}))/2 - y, the moving bound's
  mean of the bounds, and its work lam (phi(t_n) - phi(t_{n+1})) = lam (s(t_{n+1}) - s(t_n)) is the
  moving bound's: histories and ``obstacle_work`` asserted equal within 1e-10 of their scale.
* **SNES VI in the nodes' frames** (``vi_solver`` vinewtonrsls or vinewtonssls against obstacles:
  sdm_dolfinx/solvers/snes_vi_frames.py): on the inclined plane the same history as SNES VI on the unit
  rows under tilted gravity and as the gap rows' semi-smooth Newton, within 1e-9 of each column's scale
  (measured 5e-11).
* What the gap rows do not take yet is refused in one line (the
  schemes that do not say when they impose a bound, SNES VI and the other linear strategies, an
  obstacle and a lower_bound at once, a scalar problem, an object without ``distance``), and an
  initial state inside an obstacle is refused like one below the bound.
"""
import dataclasses
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.problems import Problem, block, disc, load_file
from sdm_dolfinx.obstacles import Ball, HalfSpace
from sdm_dolfinx.run import simulate

COMM = MPI.COMM_WORLD
DEMOS = Path(__file__).resolve().parents[2] / "demos"


def _scale_diff(a, b):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(a)), 1e-300))


@pytest.mark.parametrize("pair", ["P2/P1", "P1+/P0"])
def test_a_plane_declared_as_a_signed_distance_is_the_old_bound(pair):
    kw = dict(pair=pair, dt=1e-4, T=0.02)          # the disc falls onto the foundation at t ~ 0.013
    old = simulate(disc.problem(COMM), **kw)
    p = dataclasses.replace(disc.problem(COMM), lower_bound=None, obstacles=[HalfSpace((0.0, 0.0), (0.0, 1.0))])
    new = simulate(p, **kw)
    assert max(old.timeseries["contact_force"]) > 0          # the disc did hit the plane
    assert new.info["linear_strategy_reason"].startswith("obstacles")   # through the gap rows
    tol = 1e-12 if COMM.size == 1 else 1e-10
    for c in ("energy", "contact_force", "u_probe", "gap_min_boundary", "n_active"):
        assert _scale_diff(old.timeseries[c], new.timeseries[c]) <= tol, c
    assert abs(old.info["min_gap_end"] - new.info["min_gap_end"]) <= tol


W, H, E, NU, RHO, G = 20.0, 10.0, 1000.0, 0.3, 1e-6, 9810.0


def _elastic_body(msh, grav, bottom, contact, columns, E=E, nu=NU, rho=RHO):
    """The isotropic elastic body meshed by ``msh`` (2-D or 3-D) under the gravity vector ``grav``, at rest
    and unstressed, constrained where ``bottom(x)`` (its last component bounded: ``contact`` gives the
    lower_bound or the obstacles), with the time-series ``columns``."""
    dim = msh.topology.dim
    facets = np.sort(dmesh.locate_entities_boundary(msh, dim - 1, bottom)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, dim - 1, facets, np.ones_like(facets)))(1)
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = lambda u: ufl.sym(ufl.grad(u))                                     # noqa: E731
    sigma = lambda u: lmbda * ufl.tr(eps(u)) * ufl.Identity(dim) + 2 * mu * eps(u)   # noqa: E731
    gc = fem.Constant(msh, PETSc.ScalarType(grav))
    zero = lambda x: np.zeros((dim, x.shape[1]))                             # noqa: E731
    return Problem(name="slope", mesh=msh, shape=(dim,), rho=rho,
                   a=lambda u, w: ufl.inner(sigma(u), eps(w)) * ufl.dx, l=lambda w: rho * ufl.inner(gc, w) * ufl.dx,
                   u0=zero, v0=zero, constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom),
                   constraint_component=dim - 1, constraint_measure=lambda q: q * ds_c, stress=sigma,
                   extra_columns=columns, parameters={"lame_lambda": lmbda, "lame_mu": mu}, **contact)


def _block_on_slope(theta, rotated, n=8):
    """The block W x H on the plane of inclination ``theta`` (degrees): its mesh rotated onto the
    plane through 0 with normal (-sin, cos) under vertical gravity, or axis-aligned on y >= 0 under
    gravity rotated by -theta (``rotated`` False)."""
    msh = dmesh.create_rectangle(COMM, [np.zeros(2), np.array([W, H])], [n, n // 2], dmesh.CellType.triangle)
    th = np.radians(theta)
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    nrm = np.array([-np.sin(th), np.cos(th)])
    if rotated:
        msh.geometry.x[:, :2] = msh.geometry.x[:, :2] @ R.T
        grav = np.array([0.0, -G])
        bottom = lambda x: np.isclose(nrm @ x[:2], 0.0, atol=1e-9)            # noqa: E731
        contact = dict(lower_bound=None, obstacles=[HalfSpace((0.0, 0.0), nrm)])
    else:
        grav = np.array([-G * np.sin(th), -G * np.cos(th)])
        bottom = lambda x: np.isclose(x[1], 0.0)                             # noqa: E731
        contact = dict(lower_bound=lambda x: -x[1])
    p = _elastic_body(msh, grav, bottom, contact, ("contact_force", "momentum_x", "momentum_y"))
    return p, R


@pytest.mark.parametrize("pair,constrain", [("P2/P1", "vertices"), ("P2/P1", "nodes"), ("P1+/P0", "vertices")])
def test_an_inclined_plane_is_tilted_gravity(pair, constrain):
    theta = 25.0
    kw = dict(pair=pair, dt=2e-5, T=4e-3, constrain=constrain)
    p0, R = _block_on_slope(theta, False)
    p1, _ = _block_on_slope(theta, True)
    s0, s1 = simulate(p0, **kw).timeseries, simulate(p1, **kw).timeseries
    assert max(s0["n_active"]) > 0 and max(s0["contact_force"]) > 0
    kin = max(s0["kinetic"])
    assert np.max(np.abs(np.asarray(s0["energy"]) - s1["energy"])) <= 1e-9 * kin
    for c in ("kinetic", "contact_force", "n_active"):
        assert _scale_diff(s0[c], s1[c]) <= 1e-9, c
    # the gap, to the round-off of the rotated coordinates (its scale is 0 where every node holds)
    assert np.max(np.abs(np.asarray(s0["gap_min_boundary"]) - s1["gap_min_boundary"])) <= 1e-11 * W
    p0v = np.vstack([s0["momentum_x"], s0["momentum_y"]])
    p1v = np.vstack([s1["momentum_x"], s1["momentum_y"]])
    assert np.max(np.abs(R @ p0v - p1v)) <= 1e-9 * np.max(np.abs(p0v))
    m, t, th = RHO * W * H, np.asarray(s1["t"]), np.radians(theta)
    p_slope = np.cos(th) * p1v[0] + np.sin(th) * p1v[1]
    assert np.max(np.abs(p_slope + m * G * np.sin(th) * t)) <= 1e-10 * m * G * t[-1]


@pytest.mark.parametrize("vi_solver", ["vinewtonrsls", "vinewtonssls"])
@pytest.mark.slow
def test_snes_vi_on_an_inclined_plane_is_snes_vi_under_tilted_gravity(vi_solver):
    kw = dict(pair="P1+/P0", dt=2e-5, T=4e-3)
    p0, _ = _block_on_slope(25.0, False)
    p1, _ = _block_on_slope(25.0, True)
    s0, s1 = (simulate(p, vi_solver=vi_solver, **kw).timeseries for p in (p0, p1))
    ssn = simulate(_block_on_slope(25.0, True)[0], **kw).timeseries
    assert max(s0["n_active"]) > 0
    kin = max(s0["kinetic"])
    for other in (s0, ssn):
        assert np.max(np.abs(np.asarray(other["energy"]) - s1["energy"])) <= 1e-9 * kin
        for c in ("kinetic", "contact_force", "n_active"):
            assert _scale_diff(other[c], s1[c]) <= 1e-9, c


@pytest.mark.slow
def test_a_disc_in_a_bowl_swings_with_the_pendulum_period():
    spec = load_file(DEMOS / "bowl_problem.py")
    p = spec.problem(COMM)
    T0 = p.parameters["period"]
    s = simulate(p, pair="P1+/P0", dt=T0 / 2000, T=2.2 * T0).timeseries
    t, px = np.asarray(s["t"]), np.asarray(s["momentum_x"])
    up = np.flatnonzero((px[:-1] < 0) & (px[1:] >= 0))          # x-velocity of the centre of mass: - to +
    tc = t[up] + (t[up + 1] - t[up]) * px[up] / (px[up] - px[up + 1])
    assert len(tc) >= 2
    assert abs((tc[1] - tc[0]) / T0 - 1.0) <= 0.01
    assert min(s["n_active"][1:]) >= 0 and max(s["contact_force"]) > 0


def test_the_krylov_fallback_swings_the_disc_as_the_cached_columns_do():
    """``-sdm_gap_max_columns 0``: every active set of the gap rows solved by CG on the Schur complement
    (one solve with the factorisation per product) instead of the dense system on cached columns. The
    disc in the bowl (h = 2 mm, P1+/P0, dt = T0/1000, 0.3 T0) swings the same: the same active sets at
    every step, contact force, u_probe and momentum within 1e-9 of their scale (CG stops at 1e-12 of the
    residual; measured 2.6e-11, 1.1e-12, 1.1e-12), at more solves (909 against 304, measured). On 2 ranks
    1e-6 (measured 1.1e-9): the parallel factorisation's round-off differs between the two paths and the
    sliding disc amplifies round-off (its restart is held to 1e-6 too: tests/integration/test_restart_gap_rows.py)."""
    spec = load_file(DEMOS / "bowl_problem.py")
    T0 = spec.problem(COMM).parameters["period"]
    kw = dict(pair="P1+/P0", dt=T0 / 1000, T=0.3 * T0)
    dense = simulate(spec.problem(COMM, h=2.0), **kw)
    krylov = simulate(spec.problem(COMM, h=2.0), petsc_options={"gap_max_columns": 0}, **kw)
    a, b = dense.timeseries, krylov.timeseries
    assert np.array_equal(a["n_active"], b["n_active"]) and max(a["n_active"]) > 0
    for c in ("contact_force", "u_probe", "momentum_x", "energy"):
        assert _scale_diff(a[c], b[c]) <= (1e-9 if COMM.size == 1 else 1e-6), (c, _scale_diff(a[c], b[c]))
    assert krylov.info["linear_its_total"] > dense.info["linear_its_total"]


def _rising_floor(kind, lift=0.5, omega=200.0):
    """The block on a floor rising as s(t) = lift (1 - cos(omega t)): a moving bound or a moving plane."""
    p = block.problem(COMM, nx=8, ny=4)
    s = lambda t: lift * (1.0 - np.cos(omega * t))                           # noqa: E731
    if kind == "bound":
        p.lower_bound, p.moving_bound = (lambda x, t: s(t) - x[1]), True
    else:
        p.lower_bound = None
        p.obstacles = [HalfSpace((0.0, 0.0), (0.0, 1.0), motion=lambda t: (0.0, s(t)))]
    return p


def test_a_plane_moving_along_its_normal_is_the_moving_bound():
    kw = dict(pair="P2/P1", dt=2e-4, T=0.02)
    a = simulate(_rising_floor("bound"), **kw).timeseries
    b = simulate(_rising_floor("plane"), **kw).timeseries
    assert max(a["obstacle_work"]) > 0
    for c in ("energy", "contact_force", "u_probe", "obstacle_work", "gap_min_boundary"):
        assert _scale_diff(a[c], b[c]) <= 1e-10, c


def _slope():
    return _block_on_slope(10.0, True, n=4)[0]


@pytest.mark.parametrize("given,words", [
    (dict(scheme="newmark"), "scheme 'newmark'"),
    (dict(vi_solver="vinewtonrsls", linear="cg-factor"), "vi_solver 'vinewtonrsls' takes"),
    (dict(linear="cg-factor"), "linear strategy schur"),
])
def test_what_the_gap_rows_do_not_take_is_refused(given, words):
    with pytest.raises(SdmError, match=words):
        simulate(_slope(), pair="P1+/P0", dt=1e-4, T=1e-3, **given)


def test_obstacles_are_refused_where_they_mean_nothing():
    p = _slope()
    with pytest.raises(SdmError, match="either lower_bound"):
        dataclasses.replace(p, lower_bound=lambda x: -x[1])
    with pytest.raises(SdmError, match="distance"):
        dataclasses.replace(p, obstacles=[object()])
    with pytest.raises(SdmError, match="list of obstacles"):
        dataclasses.replace(p, obstacles=HalfSpace((0.0, 0.0), (0.0, 1.0)))
    with pytest.raises(SdmError, match="no obstacles"):
        dataclasses.replace(p, obstacles=[])


def test_an_initial_state_inside_an_obstacle_is_refused():
    p = _slope()
    p.u0 = lambda x: np.tile(np.array([[0.3], [-1.0]]), (1, x.shape[1]))     # 1 mm down: into the plane
    with pytest.raises(SdmError, match="inside an obstacle"):
        simulate(p, pair="P1+/P0", dt=1e-4, T=1e-3)


@pytest.mark.parametrize("pair", ["P2/P1", "P1+/P0"])
def test_inspect_measures_the_rows_of_an_inclined_plane_as_those_of_the_flat_one(pair):
    """Condition (7) with the obstacle's rows at the reference configuration (each node's normal there):
    the block on the 25-degree plane is the axis-aligned block rotated (B and the rows rotate together,
    and beta is invariant under an orthogonal change of the displacement basis), so beta agrees to
    round-off (asserted 1e-9; measured ~1e-15)."""
    from sdm_dolfinx.analysis.infsup import inspect
    flat = inspect(_block_on_slope(25.0, False, n=6)[0], pair)["beta"]
    tilted = inspect(_block_on_slope(25.0, True, n=6)[0], pair)["beta"]
    assert flat > 0.1 and abs(tilted - flat) <= 1e-9 * flat


def test_a_dirichlet_part_at_the_nodes_an_obstacle_holds_is_refused():
    """A part prescribing u_x (not the component u_probe records) at the bottom nodes the inclined plane
    holds: their rows would take its moving data at the wrong time; refused in one line."""
    from dolfinx import mesh as dmesh
    from sdm_dolfinx.problems import DirichletPart
    p = _slope()
    th = np.radians(10.0)
    on = lambda x: np.isclose(-np.sin(th) * x[0] + np.cos(th) * x[1], 0.0, atol=1e-9)     # noqa: E731
    p.dirichlet_parts = [DirichletPart("bottom", lambda m: dmesh.locate_entities_boundary(m, 1, on),
                                       value=lambda x, t: 1e-3 * t, components=(0,))]
    with pytest.raises(SdmError, match="Dirichlet part prescribes .* the obstacles constrain"):
        simulate(p, pair="P1+/P0", dt=1e-4, T=1e-3)


def test_a_2d_problem_refuses_an_obstacle_whose_normals_leave_the_plane():
    p = _slope()
    p.obstacles = [HalfSpace((0.0, 0.0, 0.0), (0.0, 1.0, 1.0))]
    with pytest.raises(SdmError, match="not a plane-section obstacle .* n_z = 0"):
        simulate(p, pair="P1+/P0", dt=1e-4, T=1e-3)
