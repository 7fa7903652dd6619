"""The problems with closed forms for friction, checked without friction.

* the block resting on the foundation from its static equilibrium: frictionless, it slides at
  v0 for ever and the foundation carries m g at every step, for every displacement element
  (P2, P1+, P1: the static solution is solved in the run's own W^h); from rest it vibrates;
* the disc on an inclined foundation (gravity at theta to -e_y): its horizontal momentum grows
  as m g sin(theta) t, in free flight and while it presses on the foundation; an oblique impact
  keeps the horizontal momentum; the rigid disc's rolling and sliding closed forms meet at
  mu = tan(theta)/3; the default disc's load is the paper's (0, -g), formed the same way;
* the command line: --help, run.json's parameters and units, bad values in one line.

Every momentum balance is the midpoint scheme's exact one: a step solves K X = b + lam + r with
K = alpha^2 M + A, b = L + M (alpha^2 U^n + alpha Vbar^n), alpha = 2/dt, r the linear solve's
residual, so for a rigid e (e^T A = 0) e^T M (Vbar^{n+1} - Vbar^n) = dt e^T (L + lam + r). The
multipliers are normal (on the y dofs only): e_x^T lam = 0, and e_x carries the whole load's
x part. What remains is r, bounded by the solves' relative tolerance KSP_RTOL times b's size
(:func:`solve_slack`).
"""
import json

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import disc, simulate
from sdm_dolfinx.cli import main as cli_main
from sdm_dolfinx.problems import block

COMM = MPI.COMM_WORLD
G = 9810.0                       # mm/s^2, both problems' default
#: relative tolerance of every linear solve of a step (solvers.active_set.InactiveSetSolver's ksp rtol)
KSP_RTOL = 1e-12
#: a factor for the norms the bound mixes (the 1-norm of r against the 2-norm the KSP controls)
SAFETY = 10.0


def solve_slack(dt, m, u_max, v_max, g=G):
    """What one step's linear solve may leave in a momentum, over dt (N per mm of thickness):
    |e^T r| <= KSP_RTOL |b|_1, |b|_1 ~ m (alpha^2 |U|max + alpha |V|max + g) (M has row sums of
    total m), times SAFETY. A momentum drifts by at most dt times this per step, and a step's
    sum of multipliers differs from its exact value by about this (the Schur complement of K on
    the active set maps r to lam with a factor of order 1, alpha^2 M dominating A)."""
    alpha = 2.0 / dt
    return SAFETY * KSP_RTOL * m * (alpha ** 2 * u_max + alpha * v_max + g)


# ------------------------------------------------------------------------------------------ block
@pytest.mark.parametrize("pair", ["P2/P1", "P1+/P0", "P1/P1"])
def test_frictionless_block_slides_at_v0_and_carries_mg(pair):
    """From the static equilibrium (default), frictionless, 400 steps (T = 40 ms, the default run):
    U^n = U_s + v0 t_n e_x is the discrete solution (block._build's docstring), so at every step
    every bottom vertex stays in contact, u_probe = 0, momentum_x = m v0, momentum_y = 0 and the
    contact force sum(lam) = -e_y^T L = m g, all up to the solves' slack (solve_slack: 8e-6 m v0
    for the momentum over the run, 2e-6 m g per step; measured <= 2e-9 m v0 and 3e-11 m g), and
    the energy is constant up to the residual's work r . (U^{n+1} - U^n) <= slack v0 dt a step
    (2e-5 of E^0 over the run; measured <= 2.4e-9, P1+/P0). m = rho width height is exact on the rectangle.

    The static solution is solved in the pair's own element: the P2 equilibrium interpolated
    into P1+ or P1 made the contact force swing between 11 % and 185 % (P1+), 62 % and 137 % (P1)
    of m g (measured)."""
    dt, T, v0 = 1e-4, 0.04, 100.0
    p = block.problem(v0=v0)
    m = 1e-6 * 20.0 * 10.0
    ts = simulate(p, pair=pair, dt=dt, T=T).timeseries
    n = len(ts["t"]) - 1
    slack = solve_slack(dt, m, u_max=v0 * T + 1.0, v_max=v0)
    assert np.all(ts["n_active"][1:] == 11)                 # nx + 1 bottom vertices, all in contact
    assert np.max(np.abs(ts["momentum_x"] - m * v0)) <= n * dt * slack
    assert np.max(np.abs(ts["momentum_y"])) <= n * dt * slack
    assert np.max(np.abs(ts["contact_force"][1:] - m * G)) <= slack, ts["contact_force"][1:].min() / (m * G)
    assert np.max(np.abs(ts["u_probe"])) <= 1e-12           # held at the foundation (a bilateral zero)
    assert np.max(np.abs(ts["energy"] - ts["energy"][0])) <= n * dt * v0 * slack
    assert ts["lambda_probe"].min() >= 0.0 and ts["lambda_probe"][1:].min() > 0.0


def test_block_constrained_at_every_node_starts_from_its_own_equilibrium():
    """--constrain nodes (P2/P1: the bottom's mid-edge nodes held too) starts from the static solution
    with every bottom node held, so the run rests as the vertex one does: the contact force is m g at
    every step (the solves' slack) and no bottom node ever goes below the foundation (round-off),
    where the vertex constraint lets the mid-edge nodes sag 1.4e-4 mm. It was refused (the vertex
    equilibrium interpolated below the bound at 10 nodes)."""
    dt, T = 1e-4, 2e-3
    m = 1e-6 * 20.0 * 10.0
    ts = simulate(block.problem(), pair="P2/P1", dt=dt, T=T, constrain="nodes").timeseries
    slack = solve_slack(dt, m, u_max=100.0 * T + 1.0, v_max=100.0)
    assert np.max(np.abs(ts["contact_force"][1:] - m * G)) <= slack
    assert ts["gap_min_boundary"].min() >= -1e-12
    vertices = simulate(block.problem(), pair="P2/P1", dt=dt, T=T).timeseries
    assert vertices["gap_min_boundary"].min() < -1e-5                # the sag --constrain nodes removes


def test_block_dropped_from_rest_vibrates_with_the_impulse_balance():
    """--start rest: the unstressed block on the foundation sinks into its own weight and
    vibrates: the contact force swings widely around m g (measured 8 % to 192 %; we ask for
    more than +-50 %) while the vertical impulse balance dt sum_n F^{n+1} = P_y^N - P_y^0 + m g T
    holds to the solves' slack, and the horizontal momentum stays m v0."""
    dt, T, v0 = 1e-4, 0.01, 100.0
    p = block.problem(start="rest", v0=v0)
    m = block.total_mass(p)
    ts = simulate(p, pair="P2/P1", dt=dt, T=T).timeseries
    n = len(ts["t"]) - 1
    F = ts["contact_force"][1:]
    slack = solve_slack(dt, m, u_max=v0 * T + 1.0, v_max=v0)
    assert F.min() < 0.5 * m * G and F.max() > 1.5 * m * G
    residual = dt * F.sum() - (ts["momentum_y"][-1] - ts["momentum_y"][0]) - m * G * n * dt
    assert abs(residual) <= n * dt * slack, residual
    assert np.max(np.abs(ts["momentum_x"] - m * v0)) <= n * dt * slack


@pytest.mark.mpi
def test_block_one_and_two_ranks_agree():
    """The equilibrium start (a MUMPS solve) and the run on COMM_WORLD against COMM_SELF on rank
    0: the same time series to 1e-9 of each column's physical scale (as for the disc): the
    energy's, m g for the forces and stresses, m v0 for the momenta (momentum_y's exact value is
    0), the static displacement's 1e-4 mm for u_probe (exactly 0: the probe sits on the
    foundation)."""
    kw = dict(pair="P2/P1", dt=1e-4, T=0.005)
    par = simulate(block.problem(comm=COMM), **kw).timeseries
    ser = simulate(block.problem(comm=MPI.COMM_SELF), **kw).timeseries if COMM.rank == 0 else None
    ser = COMM.bcast(ser, root=0)
    np.testing.assert_array_equal(par["n_active"], ser["n_active"])
    m = 2e-4
    scales = {"energy": np.max(np.abs(ser["energy"])), "u_probe": 1e-4, "lambda_probe": m * G / 20.0,
              "contact_force": m * G, "momentum_x": m * 100.0, "momentum_y": m * 100.0}
    for c, scale in scales.items():
        np.testing.assert_allclose(par[c], ser[c], rtol=0, atol=1e-9 * scale, err_msg=c)


# ------------------------------------------------------------------------------------------- disc
def test_disc_gravity_angle_zero_is_the_papers_load():
    """theta = 0 forms (0, -g) itself (the default disc's runs stay bit-identical: measured against
    the disc before the angle, through the impact, every column equal); theta > 0 gives
    g (sin theta, -cos theta), of length g."""
    g0 = disc.gravity_vector(G, 0.0)
    assert g0.tolist() == [0.0, -G] and not np.signbit(g0[0])
    g30 = disc.gravity_vector(G, 30.0)
    assert abs(g30[0] - 0.5 * G) < 1e-12 * G and abs(g30[1] + np.sqrt(3) / 2 * G) < 1e-12 * G
    assert abs(np.hypot(*disc.gravity_vector(G, 89.0)) - G) < 1e-12 * G


@pytest.mark.filterwarnings("ignore::sdm_dolfinx.run.result.BoundaryGapWarning")
def test_disc_on_an_incline_gains_momentum_m_g_sin_theta_t():
    """theta = 30 degrees, frictionless, from rest just touching (height 0, v0 0: the constraint
    holds with equality at A at t = 0): the disc presses on the foundation at every step
    (sum lam > 0) and, lam being normal, its horizontal momentum is m g sin(theta) t exactly
    (solves' slack: 1.3e-7 of m g sin(theta) T; measured 4e-14). Also in free flight (no foundation,
    vx0 = 200 mm/s): (vx0 + g sin theta t, v0 - g cos theta t) m."""
    dt, T, theta = 1e-4, 0.004, 30.0
    s, c = np.sin(np.deg2rad(theta)), np.cos(np.deg2rad(theta))
    p = disc.problem(level=1, height=0.0, v0=0.0, gravity_angle=theta)
    m = disc.total_mass(p)
    ts = simulate(p, pair="P2/P1", dt=dt, T=T).timeseries
    n, t = len(ts["t"]) - 1, ts["t"]
    assert ts["u_probe"][0] == 0.0 and np.all(ts["n_active"][1:] >= 1) and np.all(ts["contact_force"][1:] > 0)
    slack = solve_slack(dt, m, u_max=G * T ** 2, v_max=G * T)
    assert np.max(np.abs(ts["momentum_x"] - m * G * s * t)) <= n * dt * slack
    free = simulate(disc.problem(level=1, with_contact=False, gravity_angle=theta, vx0=200.0),
                    pair="P2/P1", dt=dt, T=T).timeseries
    slack = solve_slack(dt, m, u_max=1000.0 * T, v_max=1000.0 + G * T)
    assert np.max(np.abs(free["momentum_x"] - m * (200.0 + G * s * t))) <= n * dt * slack
    assert np.max(np.abs(free["momentum_y"] - m * (-1000.0 - G * c * t))) <= n * dt * slack


@pytest.mark.filterwarnings("ignore::sdm_dolfinx.run.result.BoundaryGapWarning")
def test_oblique_frictionless_impact_keeps_the_horizontal_momentum():
    """v0 = (500, -1000) mm/s from 1 mm above the foundation, T = 6 ms (the impact starts at
    step 11 and is under way at the end): the normal multipliers change P_y by hundreds of
    percent, P_x = m vx0 throughout (slack 3e-7 relative; measured 1e-13)."""
    dt, T, vx0, v0 = 1e-4, 0.006, 500.0, -1000.0
    p = disc.problem(level=1, height=1.0, vx0=vx0, v0=v0)
    m = disc.total_mass(p)
    ts = simulate(p, pair="P2/P1", dt=dt, T=T).timeseries
    n = len(ts["t"]) - 1
    assert ts["n_active"].max() >= 1 and ts["momentum_y"][-1] > 0          # it bounced
    slack = solve_slack(dt, m, u_max=abs(v0) * T, v_max=np.hypot(vx0, v0))
    assert np.max(np.abs(ts["momentum_x"] - m * vx0)) <= n * dt * slack


@pytest.mark.parametrize("theta", [5.0, 30.0, 60.0])
def test_rolling_and_sliding_meet_at_mu_tan_theta_over_3(theta):
    """disc.incline_motion: at mu = tan(theta)/3 both regimes give a = (2/3) g sin theta and
    alpha = a / R (the contact point's slip rate a - alpha R vanishes); below it the disc slides
    faster than it would roll, frictionless at g sin theta; no regime moves at theta = 0."""
    R = 20.0
    mu_roll = np.tan(np.deg2rad(theta)) / 3.0
    roll = disc.incline_motion(G, theta, mu_roll, R)
    slide = disc.incline_motion(G, theta, mu_roll * (1 - 1e-12), R)
    assert roll["regime"] == "rolling" and slide["regime"] == "sliding"
    assert abs(roll["a"] - 2.0 / 3.0 * G * np.sin(np.deg2rad(theta))) < 1e-12 * G
    assert abs(slide["a"] - roll["a"]) < 1e-9 * G and abs(slide["alpha"] - roll["alpha"]) < 1e-9 * G / R
    assert abs(roll["a"] - roll["alpha"] * R) < 1e-12 * G
    low = disc.incline_motion(G, theta, 0.5 * mu_roll, R)
    assert low["a"] > roll["a"] and low["a"] - low["alpha"] * R > 0
    assert disc.incline_motion(G, theta, 0.0, R)["a"] == pytest.approx(G * np.sin(np.deg2rad(theta)), rel=1e-14)
    assert disc.incline_motion(G, 0.0, 0.3, R)["a"] == 0.0


# ------------------------------------------------------------------------------------ command line
def _stdout_of(argv, capsys):
    capsys.readouterr()
    try:
        status = cli_main(argv)
    except SystemExit as e:         # argparse's --help
        status = e.code
    return status, capsys.readouterr().out


def test_help_shows_the_new_options(capsys):
    status, out = _stdout_of(["block", "--help"], capsys)
    if COMM.rank == 0:
        assert status in (0, None)
        for opt in ("--width", "--height", "--nx", "--ny", "--E", "--nu", "--rho", "--gravity", "--v0", "--start"):
            assert opt in out, opt
        assert "v0 / (mu g)" in out                       # the closed forms are in the description
    status, out = _stdout_of(["disc", "--gravity-angle", "30", "--help"], capsys)
    if COMM.rank == 0:
        assert status in (0, None) and "--gravity-angle THETA" in out and "--vx0" in out and "degrees" in out


def test_run_json_records_the_new_parameters(mpi_tmp_path):
    """The disc's gravity_angle and vx0 with their units, the momentum_x column; the block's
    parameters, its start and the closed-form mass."""
    out = mpi_tmp_path / "disc"
    argv = ["disc", "--gravity-angle", "30", "--vx0", "100", "--dt", "1e-4", "--T", "0.0005", "--out", str(out)]
    assert cli_main(argv + ["--quiet"]) == 0
    bout = mpi_tmp_path / "block"
    assert cli_main(["block", "--nx", "4", "--ny", "2", "--T", "0.0005", "--out", str(bout), "--quiet"]) == 0
    if COMM.rank == 0:
        info = json.loads((out / "run.json").read_text())["problem"]
        assert info["parameters"]["gravity_angle"] == 30.0 and info["parameters"]["vx0"] == 100.0
        assert info["units"]["gravity_angle"].startswith("degrees") and info["units"]["vx0"].startswith("mm/s")
        assert info["args"]["gravity_angle"] == 30.0
        header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
        assert "momentum_x" in header and "momentum_y" in header
        binfo = json.loads((bout / "run.json").read_text())["problem"]
        assert binfo["name"] == "block" and binfo["parameters"]["start"] == "equilibrium"
        assert binfo["parameters"]["mass"] == pytest.approx(2e-4, rel=1e-14)
        for k in ("width", "height", "E", "nu", "rho", "gravity", "v0", "start"):
            assert k in binfo["units"], k
    COMM.Barrier()


@pytest.mark.parametrize("argv,message", [
    (["disc", "--gravity-angle", "90"], "--gravity-angle must be in [0, 90) degrees"),
    (["disc", "--gravity-angle", "-5"], "--gravity-angle must be >= 0"),
    (["disc", "--gravity-angle", "nan"], "--gravity-angle must be a finite number"),
    (["block", "--width", "-20"], "--width must be > 0"),
    (["block", "--height", "0"], "--height must be > 0"),
    (["block", "--nx", "0"], "--nx must be >= 1"),
    (["block", "--nu", "0.5"], "--nu must be <= 0.49"),
    (["block", "--gravity", "-9810"], "--gravity must be >= 0"),
    (["block", "--start", "moving"], "invalid choice"),
    (["disc", "--start", "equilibrium", "--height", "0", "--v0", "0", "--constrain", "nodes"],
     "disc --start equilibrium: no static solution with the constraint at every node (constrain nodes)"),
])
def test_bad_values_are_refused_in_one_line(argv, message, mpi_tmp_path, capsys):
    out = mpi_tmp_path / "never"
    capsys.readouterr()
    assert cli_main(argv + ["--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert not out.exists()
