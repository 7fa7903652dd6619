"""The penalty and Nitsche treatments on gap rows: ``contact="penalty"`` with fixed obstacles or
``--constrain weighted`` (springs lam_i = k_i (g_i - G_i X)_+ on the rows, solved by the gap-row Newton
with the compliances 1/k on its Schur complement's diagonal: sdm_dolfinx/contact/penalty.py), and
``contact="nitsche"`` with fixed obstacles (u . n >= bound with n and bound Lagrange fields set before
every step from the obstacle at the current configuration: sdm_dolfinx/contact/nitsche.py).

* **Rotation invariance.** The block of test_obstacle_contact.py on a 25-degree inclined plane (mesh
  rotated, vertical gravity, a HalfSpace obstacle) against the axis-aligned block on the unit rows'
  treatment under gravity rotated by -25 degrees. Nitsche's term reads u . n and sigma(u) nu . n, both
  invariant, and gamma's modulus sigma_nn of a unit normal strain is lambda + 2 mu whatever the normal.
  The penalty's springs' stiffness epsilon = penalty x (mesh
  stiffness at the contact) is taken along each node's normal (n^T A_ii n, A_ii its diagonal block),
  which rotation leaves unchanged, so the discrete problems are the same up to the rotation: kinetic and
  contact energies and contact forces within 1e-9 of their scale (measured 3e-11), and the energy
  (kinetic + potential + contact_energy, conserved by the midpoint scheme to 1e-13 of the kinetic
  energy here) within 1e-9 of the largest kinetic energy. With epsilon from A_cc at the constrained
  component (the unit rows' rule) the rotated run differed by 11 % (measured): that rule is not
  rotation invariant.
* **Springs in series with the weighted gap** (demos/pushed_block_problem.py: the top pushed down by d
  = 10 um, nu = 0, the weighted rows' patch test of test_weighted_gap.py). The springs under the face
  carry the same force as the block, so the face sinks uniformly by delta and the block shortens by
  d - delta: the force is F (1 - delta / d) with F = E W d / H the exact contact's (asserted within 0.5 %
  for the punch's reaction and the foundation's force, with delta the face's sink at the end; measured
  2e-4), and the springs' law holds: delta = F' / (epsilon W) within 1 % (measured 4e-4 on P2/P1, 3e-3
  on P1+/P0; the rows are averages, so each one's force is epsilon m_i delta for a uniform sink). The penalty at its default (1) makes delta 14 % of d on P2/P1,
  7 % on P1+/P0 (measured): the penalty is compliant, the exact contact is not.
* **A curved obstacle**: the disc in the bowl (demos/bowl_problem.py, P1+/P0, frictionless) swings
  with the pendulum's period under each treatment: its first half period (the momentum's first upward
  zero) within 1 % of T(theta0) / 2 (measured: exact +0.17 %, penalty +0.29 %, Nitsche -0.65 %; SNES VI
  in the nodes' frames, the exact contact's +0.17 %).
* **A moving obstacle with the penalty**: its contact energy is taken at the state's time, and on a
  rising plane E + contact_energy - obstacle_work is conserved to round-off while the set of compressed
  springs does not change. Nitsche against a moving obstacle is refused in one line, as is Nitsche with
  the weighted gap (test_weighted_gap.py).
"""
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
from scipy.special import ellipk

from sdm_dolfinx.contact.penalty import stiffness_scale
from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.obstacles import HalfSpace
from sdm_dolfinx.problems import load_file
from sdm_dolfinx.run import simulate

from test_obstacle_contact import _block_on_slope, _rising_floor, _scale_diff

COMM = MPI.COMM_WORLD
PUSHED = Path(__file__).resolve().parents[2] / "demos" / "pushed_block_problem.py"
BOWL = Path(__file__).resolve().parents[2] / "demos" / "bowl_problem.py"
PUSH = 0.01


@pytest.mark.parametrize("contact,pair,constrain", [("penalty", "P1+/P0", "vertices"), ("penalty", "P2/P1", "nodes"),
                                                    ("nitsche", "P1+/P0", "vertices"), ("nitsche", "P2/P1", "vertices")])
def test_a_treatment_on_an_inclined_plane_is_the_treatment_under_tilted_gravity(contact, pair, constrain):
    kw = dict(pair=pair, constrain=constrain, dt=2e-5, T=4e-3, contact=contact)
    p0, _ = _block_on_slope(25.0, False)
    p1, _ = _block_on_slope(25.0, True)
    r0, r1 = simulate(p0, **kw), simulate(p1, **kw)
    s0, s1 = r0.timeseries, r1.timeseries
    assert max(s0["contact_energy"]) > 0 and r1.info["min_gap_end"] < 0        # the springs work, it penetrates
    for c in ("kinetic", "contact_force", "n_active"):
        assert _scale_diff(s0[c], s1[c]) <= 1e-9, c
    assert _scale_diff(s0["contact_energy"], s1["contact_energy"]) <= 1e-8      # Nitsche's: a difference of squares
    kin = max(s0["kinetic"])
    assert np.max(np.abs(np.asarray(s0["energy"]) - s1["energy"])) <= 1e-9 * kin
    # the penetration, to the round-off of the rotated coordinates (1e-11 of the block's width 20 mm)
    assert abs(r0.info["min_gap_end"] - r1.info["min_gap_end"]) <= 1e-9 * abs(r0.info["min_gap_end"]) + 2e-10


@pytest.mark.parametrize("pair", ["P2/P1", "P1+/P0"])
def test_penalty_springs_in_series_with_the_weighted_gap(pair):
    r = simulate(str(PUSHED), {"nu": 0.0}, pair=pair, constrain="weighted", contact="penalty")   # dt 1e-4, T 10 ms
    ts = r.timeseries
    p = load_file(PUSHED).problem(COMM, nu=0.0)
    F, W = p.parameters["force"], p.args["width"]
    hold = ts["t"] > 5e-3 * (1 + 1e-9)
    delta = -ts["gap_min_boundary"][-1]
    assert delta > 0.01 * PUSH                                              # the springs give way
    force = -ts["reaction_top_y"][hold].mean()
    assert force == pytest.approx(F * (1 - delta / PUSH), rel=5e-3)
    assert ts["contact_force"][hold].mean() == pytest.approx(force, rel=5e-3)
    epsilon = stiffness_scale(r.discretisation)                             # penalty 1 (the default)
    assert delta == pytest.approx(force / (epsilon * W), rel=1e-2)


@pytest.mark.parametrize("contact,vi_solver", [("exact", "ssn"), ("penalty", "ssn"),
                                               pytest.param("nitsche", "ssn", marks=pytest.mark.slow),
                                               pytest.param("exact", "vinewtonrsls", marks=pytest.mark.slow)])
def test_a_disc_in_a_bowl_swings_with_the_pendulum_period_under_every_treatment(contact, vi_solver):
    spec = load_file(BOWL)
    p = spec.problem(COMM)
    T0, theta0 = p.parameters["period"], np.radians(p.args["theta0"])
    half = 0.5 * T0 * 2.0 * ellipk(np.sin(0.5 * theta0) ** 2) / np.pi
    run = dict(contact=contact) if vi_solver == "ssn" else dict(vi_solver=vi_solver)
    ts = simulate(p, pair="P1+/P0", dt=T0 / 1000, T=0.6 * T0, **run).timeseries
    t, px = np.asarray(ts["t"]), np.asarray(ts["momentum_x"])
    up = np.flatnonzero((px[:-1] < 0) & (px[1:] >= 0))
    assert len(up) >= 1
    k = up[0]
    crossing = t[k] + (t[k + 1] - t[k]) * px[k] / (px[k] - px[k + 1])
    assert crossing == pytest.approx(half, rel=1e-2)


def test_nitsche_refuses_a_moving_obstacle():
    p, _ = _block_on_slope(0.0, True, n=4)
    p.obstacles = [HalfSpace((0.0, 0.0), (0.0, 1.0), motion=lambda t: (0.0, 0.1 * t))]
    with pytest.raises(SdmError, match="that move, which contact 'nitsche'"):
        simulate(p, pair="P1+/P0", dt=1e-4, T=1e-3, contact="nitsche")


@pytest.mark.parametrize("pair", ["P1+/P0", "P2/P1"])
def test_the_penalty_on_a_moving_plane_conserves_energy_less_the_obstacles_work(pair):
    """The block (start unstressed, frictionless) on a floor rising as s(t) = 0.1 (1 - cos 200 t) mm with
    the penalty, stepped by hand. Its springs' force k s(X) at the midpoint state, s = g(t) - G U affine in
    U and t on a plane (the rows at the mean of the two times), is their energy's exact difference
    quotient: while every spring stays compressed (at U^n and U^{n+1}, hence at X), (E + contact energy)
    changes by sum_i lam_i (g_i(t_{n+1}) - g_i(t_n)), the obstacle's work, the contact energy taken at the
    state's time. Asserted at every such step (at least 20; the block bounces in between, where a spring's
    kink is crossed and it does not hold): within 1e-9 of the energy, the round-off of the step's
    right-hand side alpha^2 M U (the block slides 4 mm at 100 mm/s: |b| ~ 1e5 N against E ~ 1.4 N mm;
    measured 1e-14 at the start, 1.4e-10 at the end, growing with U)."""
    from sdm_dolfinx.method.discretisation import Discretisation
    from sdm_dolfinx.run.integrator import Integrator
    p = _rising_floor("plane", lift=0.1)
    p.u0 = lambda x: np.zeros((2, x.shape[1]))
    d = Discretisation(p, pair)
    dt = 2e-4
    integ = Integrator(d, "midpoint", dt, contact="penalty")
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    rows, comm = d.obstacle_rows, d.comm

    def state(t):
        held = comm.allreduce(bool(np.all(rows.phi(U.array_r, t) < 0.0)), op=MPI.LAND)
        return sum(integ.energies(U, V, t)) + integ.contact_energy(U, t), held
    E0, held0 = state(0.0)
    changes, scale = [], abs(E0)
    for n in range(200):
        info = integ.step(U, V, n, n * dt)
        E1, held1 = state((n + 1) * dt)
        if held0 and held1:
            changes.append(E1 - E0 - info["obstacle_work"])
        scale = max(scale, abs(E1))
        E0, held0 = E1, held1
    integ.destroy()
    assert len(changes) >= 20
    assert np.max(np.abs(changes)) <= 1e-9 * scale, np.max(np.abs(changes)) / scale


def test_nitsche_against_an_obstacle_reports_the_first_states_contact_energy():
    """Nitsche's contact energy theta/2 int ([P]_-^2 - sigma_n^2) / gamma is not zero for a stressed body
    off the obstacle (-sigma_n^2). The block lifted by 0.01 mm and compressed (u0 = (0, 0.01 - 1e-3 y)),
    rotated onto the 25-degree plane, against the axis-aligned one under tilted gravity: the same contact
    energy at every recorded state, the first included (it was 0 there: the obstacle's fields are set
    by the steps, and the first state is recorded before the first step)."""
    p0, R = _block_on_slope(25.0, False)
    p1, _ = _block_on_slope(25.0, True)
    p0.u0 = lambda x: np.vstack([np.zeros(x.shape[1]), 0.01 - 1e-3 * x[1]])       # noqa: E731

    def rotated(x):
        y = R.T @ x[:2]
        return R @ np.vstack([np.zeros(x.shape[1]), 0.01 - 1e-3 * y[1]])
    p1.u0 = rotated
    kw = dict(pair="P1+/P0", dt=2e-5, T=1e-4, contact="nitsche")
    s0, s1 = simulate(p0, **kw).timeseries, simulate(p1, **kw).timeseries
    assert s0["contact_energy"][0] < 0
    assert _scale_diff(s0["contact_energy"], s1["contact_energy"]) <= 1e-8
