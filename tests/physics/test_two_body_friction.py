"""Friction between two deformable bodies (``Problem.contact_pairs`` with ``friction``: the slip is the
slave vertex's motion relative to the master surface, sdm_dolfinx/method/body_rows.py) checked against
what holds exactly.

* A block sliding on an elastic base (demos/sliding_blocks_problem.py: plane strain, gravity, the base
  clamped below, non-matching faces). The base's top is flat, so wherever every slave vertex in contact
  slips backwards the friction force on the slider is -mu times the normal force N(t), and the slider's
  momentum balance (the derivation in the problem file) gives p_x(t) - p_x(0) = -mu (p_y(t) - p_y(0) +
  m g t): the friction impulse is mu times the normal impulse whatever the slider's vertical vibration.
  Measured over 10 ms (400 steps, no vertex sticks): 3e-11 relative on 1 and 2 ranks; 1e-8 of m v0
  asserted. Started near the base's rim, the slider's end vertex slides off it and loses its row (contact
  and friction) (the solver's tolerance is 1e-10 of the right-hand side). Tresca (a threshold s per unit
  length, at every slave vertex): the force is s L while every vertex slips, so p_x(t) = m v0 - s L t;
  measured to 5e-12 of m v0, 1e-8 asserted. Friction only dissipates: ``dissipated`` never decreases.
  The energy balance E + dissipated holds within 0.08 % (Coulomb, measured over the 10 ms with the slider
  landing from 1 um and sliding 0.9 mm over the deforming base: the re-projection of the sliding vertices,
  docs/contact.md); 0.5 % asserted. With the weighted gap (constrain='weighted', the rows averaged over
  the slave face with one frame a row: the base's normal and tangent, so the identity holds as it does
  at vertices): measured 1.6e-11 of m v0, the balance 0.08 %; the same bounds asserted.
* An oblique collision of two balls (the built-in two_balls at level 1, ball 1 at (vt, 0, -v), ball 2
  at (0, 0, v), Coulomb mu): the contact forces are equal and opposite on the two balls, so the total
  momentum is constant to round-off in each component (measured 6.7e-13 of m v; 1e-10 asserted, as for the
  frictionless pairs). Per vertex |lam_T| <= mu lam_N, so the tangential impulse sum lam_T dt never exceeds
  mu times the normal one. Rigid spheres (equal masses m, radii R, J_n = m (v1 + v2) for an elastic normal
  rebound) slide throughout when stopping the contact point's tangential velocity vt would take more than
  mu J_n: the tangential impulse that stops it is m vt / 7 (the relative tangential velocity of the contact
  points changes by J_t (2 / m) (1 + R^2 / k^2) = 7 J_t / m, k^2 = 2 R^2 / 5). At mu = 0.1, vt = 300 mm/s
  (m vt / 7 = 0.21 m v > mu J_n = 0.2 m v) every vertex in contact slips at every step and the tangential
  impulse is mu times the normal one: measured 0.9991 mu (the vertices' tangents differ slightly in
  direction); [0.99, 1] mu asserted. On the balls' momenta the normal impulse turns with the line of
  centres as ball 1 slides (1.2 mm during the contact), so ball 1's x-momentum changes by 0.085 of its
  z-momentum's change: below mu, asserted. At mu = 0.3, vt = 100 mm/s the contact point sticks (m vt / 7 =
  0.14 m v < mu J_n = 0.6 m v) and rigid spheres leave rolling with J_t = m vt / 7: measured 2.0 % below
  (the elastic balls' tangential compliance, Maw, Barber and Fawcett 1976), 5 % asserted.
"""
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx.problems import load_file, two_balls
from sdm_dolfinx.run import simulate

COMM = MPI.COMM_WORLD
DEMOS = Path(__file__).resolve().parents[2] / "demos"


def _slider(friction, T=0.01, x0=None, constrain="vertices", **options):
    p = load_file(DEMOS / "sliding_blocks_problem.py").problem(COMM, x0=x0)
    ts = simulate(p, pair="P2/P1", dt=2.5e-5, T=T, friction=friction, friction_options=options,
                  constrain=constrain).timeseries
    q = p.parameters
    return ts, q["mass"], q["v0"], q["gravity"], q["width"]


@pytest.mark.mpi
@pytest.mark.parametrize("constrain", ["vertices", "weighted"])
def test_coulomb_slider_takes_mu_times_the_normal_impulse(constrain):
    mu = 0.3
    ts, m, v0, g, _ = _slider("coulomb", mu=mu, constrain=constrain)
    px, py, t = ts["momentum_slider_x"], ts["momentum_slider_y"], ts["t"]
    assert px[0] == pytest.approx(m * v0, rel=1e-12)
    assert np.max(ts["n_stick"]) == 0 and np.max(ts["n_slip"]) > 0                # sliding throughout
    np.testing.assert_allclose(px - px[0], -mu * (py - py[0] + m * g * t), rtol=0.0, atol=1e-8 * m * v0)
    assert np.all(np.diff(ts["dissipated"]) >= -1e-12 * ts["energy"][0])
    assert ts["dissipated"][-1] > 0.4 * ts["energy"][0]
    e = ts["energy"] + ts["dissipated"]
    assert np.max(np.abs(e / e[0] - 1.0)) <= 5e-3


@pytest.mark.mpi
def test_tresca_slider_decelerates_at_s_L_over_m():
    s = 0.0333
    ts, m, v0, _, width = _slider("tresca", tresca_threshold=s)
    assert np.max(ts["n_stick"]) == 0
    np.testing.assert_allclose(ts["momentum_slider_x"], m * v0 - s * width * ts["t"], rtol=0.0, atol=1e-8 * m * v0)
    assert np.all(np.diff(ts["dissipated"]) >= -1e-12 * ts["energy"][0])


@pytest.mark.parametrize("law, options", [("tresca", {"tresca_threshold": 0.0333}), ("coulomb", {"mu": 0.3})])
@pytest.mark.mpi
def test_a_vertex_sliding_off_the_base_loses_its_row_and_its_friction(law, options):
    """The slider's right end starts 0.06 mm from the base's right rim and slides past it: that slave vertex
    then has no master point, so its row holds nothing (neither contact nor friction, whatever it held the
    step before: a stuck or active row that became empty made the Newton system singular). Tresca: the force
    is s L while all 11 vertices hold, then s (L - h/2) (the end vertex's lumped length is h/2 = 1 mm)."""
    ts, m, v0, _, width = _slider(law, T=1.5e-3, x0=39.94, **options)
    assert np.max(ts["n_slip"]) == 11 and ts["n_slip"][-1] == 10 and np.max(ts["n_stick"]) == 0
    if law == "tresca":
        s = options["tresca_threshold"]
        force = ts["tangential_force"][1:]
        held = ts["n_slip"][1:] == 11
        np.testing.assert_allclose(force[held], -s * width, rtol=1e-10)
        np.testing.assert_allclose(force[~held], -s * (width - 1.0), rtol=1e-10)
    assert np.all(np.diff(ts["dissipated"]) >= -1e-12 * ts["energy"][0])


def _oblique(mu, vt):
    p = two_balls.problem(COMM, level=1, vt=vt)
    dt = 4e-5
    ts = simulate(p, pair="P2/P1", dt=dt, T=5e-3, friction="coulomb", friction_options={"mu": mu}).timeseries
    m, v = p.parameters["mass1"], p.parameters["v"]
    J = {b: np.array([ts[f"momentum_{b}_{a}"] - ts[f"momentum_{b}_{a}"][0] for a in "xyz"]) for b in ("ball1", "ball2")}
    return ts, dt, m, v, J


@pytest.mark.mpi
@pytest.mark.slow
def test_oblique_balls_sliding_exchange_mu_times_the_normal_impulse():
    mu = 0.1
    ts, dt, m, v, J = _oblique(mu, 300.0)
    assert np.max(np.abs(J["ball1"] + J["ball2"])) <= 1e-10 * m * v               # equal and opposite
    assert np.max(ts["n_stick"]) == 0
    normal = np.sum(ts["contact_force"]) * dt
    tangential = np.linalg.norm([np.sum(ts[f"tangential_force_{a}"]) * dt for a in "xyz"])
    assert normal == pytest.approx(2.0 * m * v, rel=0.05)
    assert 0.99 * mu * normal <= tangential <= mu * normal * (1.0 + 1e-8)
    assert abs(J["ball1"][0, -1]) <= mu * abs(J["ball1"][2, -1])
    assert np.all(np.diff(ts["dissipated"]) >= -1e-12 * ts["energy"][0])
    e = ts["energy"] + ts["dissipated"]
    assert np.max(np.abs(e / e[0] - 1.0)) <= 0.01


@pytest.mark.mpi
@pytest.mark.slow
def test_oblique_balls_sticking_leave_rolling():
    mu, vt = 0.3, 100.0
    ts, dt, m, v, J = _oblique(mu, vt)
    assert np.max(ts["n_stick"]) > 0
    assert np.max(np.abs(J["ball1"] + J["ball2"])) <= 1e-10 * m * v
    assert -J["ball1"][0, -1] == pytest.approx(m * vt / 7.0, rel=0.05)
    assert abs(J["ball1"][0, -1]) <= mu * abs(J["ball1"][2, -1])
