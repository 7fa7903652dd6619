"""Finite strain in contact: a neo-Hookean disc rolls one revolution without slipping on a frictional
plane, and the linear model cannot (its rotations are infinitesimal); a disc slides in a curved bowl (gap rows
linearised at U^n) with the pendulum's period. Runs on 1 and 2 ranks.

The disc (R = 20 mm, level 1, P2/P1, gravity) starts at v = 1000 mm/s with omega R = v, Coulomb mu = 1, for
2 pi R / v (629 steps of 2e-4 s; :func:`sdm_dolfinx.validation.finite_strain.rolling` measures it)."""
import warnings
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import simulate
from sdm_dolfinx.problems import load_file
from sdm_dolfinx.errors import StepError
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.run import finite_strain_step
from sdm_dolfinx.validation.finite_strain import rolling

COMM = MPI.COMM_WORLD


@pytest.fixture(scope="module")
def runs():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")         # the P2 face's sink between the vertices (measured, 0.18 mm)
        return {m: rolling(m, dt=2e-4) for m in ("neo-hookean", "linear")}


def test_disc_rolls_a_revolution_without_slipping(runs):
    """One revolution of rolling: the centre advances 2 pi R per turn within 1 % (measured 0.9970: the
    discrete disc is a polygon of ~23 vertices, compressed by its weight), every active vertex that moves in a
    step is one the step counts as slipping (in stick the contact point does not move at all: the stick set
    imposes X_t = U^n_t exactly), and the step's energy balance E^{n+1} - E^n = lam_N . (U^{n+1} - U^n)_N -
    (the step's friction dissipation) holds to the Newton tolerance (measured 5e-13 of E0)."""
    r = runs["neo-hookean"]
    assert r["turns"] == pytest.approx(1.0, abs=0.01)
    assert r["advance_per_revolution"] == pytest.approx(1.0, abs=0.01)
    assert r["moved_unslipping"] == 0
    assert r["slip_steps"] < 0.1 * r["steps"] and r["contact_steps"] > 0.5 * r["steps"]
    assert r["balance"] < 1e-9


def test_rolling_energy_changes_by_the_contacts_work_only(runs):
    """The energy is conserved up to the vertices' arrivals on the plane: it stays within 0.5 % of E0
    (measured 0.16 %; 0.10 % at dt 1e-4, 0.03 % at 5e-5), and friction dissipates less than 0.1 % (stick:
    no work)."""
    r = runs["neo-hookean"]
    assert r["energy_drift"] < 5e-3
    assert r["dissipated"][-1] < 1e-3 * r["energy"][0]


def test_linear_model_cannot_roll(runs):
    """The linear model on the same disc: its velocity field is an infinitesimal rotation, its vertices move
    on straight lines and are dragged along the plane, and friction brakes it: it advances less than half of
    2 pi R and loses more than 5 % of its energy (measured 0.39 and 8.3 %), all of it to friction (the balance
    holds)."""
    r = runs["linear"]
    assert r["advance"] < 0.5
    assert r["energy_drift"] > 0.05 and r["dissipated"][-1] > 0.05 * r["energy"][0]
    assert r["balance"] < 1e-9


@pytest.mark.parametrize("law, options", [("tresca", {"tresca_threshold": 0.5}), ("coulomb", {"mu": 0.3})])
@pytest.mark.filterwarnings("ignore::UserWarning")          # the P2 face's sink between vertices (measured)
def test_friction_laws_run_with_a_hyperelastic_disc(law, options):
    """Both friction laws take a hyperelastic material: the disc hitting the plane obliquely (level 1, 40
    steps) slides, friction dissipates, and the tangential momentum changes by the friction impulse at every
    step, p_x^{n+1} - p_x^n = dt sum lam_T (no tangential load), to the Newton tolerance."""
    dt = 2.5e-4
    ts = simulate("disc", {"level": 1, "vx0": 2000.0, "height": 0.05}, material="neo-hookean",
                  friction=law, friction_options=options, dt=dt, T=0.01).timeseries
    assert ts["n_active"].max() >= 1 and ts["dissipated"][-1] > 0.0 and ts["n_slip"].max() >= 1
    p = ts["momentum_x"]
    assert np.max(np.abs(np.diff(p) - dt * ts["tangential_force"][1:])) < 1e-9 * abs(p[0])
    assert abs(p[-1] - p[0]) > 1e-3 * abs(p[0])                 # the impulse is not idle


def test_contact_pairs_are_refused():
    """Contact pairs between bodies do not take a hyperelastic material yet: refused in one line."""
    with pytest.raises(DiscretisationError) as e:
        simulate("two_balls", {"level": 1}, material="neo-hookean", dt=4e-5, T=4e-5)
    assert "contact pairs" in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("law,value,state", [("coulomb", 0.3, "slides"), ("coulomb", 0.6, "sticks"),
                                             ("tresca", 0.02, "slides")])
def test_friction_on_an_inclined_obstacle_is_friction_under_tilted_gravity(law, value, state):
    """Rotation invariance with a hyperelastic material (isotropic: psi(R C R^T) = psi(C)): the block meshed
    rotated on a 25-degree inclined plane (an obstacle: friction in each node's frame, the rows at U^n) and
    the block axis-aligned on the unit rows under gravity R^T g take the same steps: the same sets, and
    energies, dissipation, contact forces within 1e-6 of each column's scale, the momentum rotated by R (the
    linear runs' check, tests/physics/test_obstacle_friction.py, there within 1e-9). The bound is the Newton
    tolerance, 1e-10 of the step's scale max |b|, which at dt = 2e-5 is dominated by the mass term 4 M U / dt^2:
    measured 1.0e-7 (the contact force under Tresca friction), 1e-10 elsewhere."""
    from test_obstacle_contact import _block_on_slope, _scale_diff
    option = {"mu": value} if law == "coulomb" else {"tresca_threshold": value}
    kw = dict(pair="P1+/P0", dt=2e-5, T=4e-3, friction=law, friction_options=option, material="neo-hookean")
    p0, R = _block_on_slope(25.0, False)
    p1, _ = _block_on_slope(25.0, True)
    s0, s1 = simulate(p0, **kw).timeseries, simulate(p1, **kw).timeseries
    assert max(s0["contact_force"]) > 0
    assert s0["n_slip"][-1] + s0["n_stick"][-1] > 0 and (s0["n_stick"][-1] > 0) == (state == "sticks")
    for c in ("n_active", "n_stick", "n_slip"):
        assert np.array_equal(s0[c], s1[c]), c
    for c in ("energy", "kinetic", "contact_force", "dissipated", "tangential_force"):
        assert _scale_diff(s0[c], s1[c]) <= 1e-6, c
    p0v = np.vstack([s0["momentum_x"], s0["momentum_y"]])
    p1v = np.vstack([s1["momentum_x"], s1["momentum_y"]])
    assert np.max(np.abs(R @ p0v - p1v)) <= 1e-6 * np.max(np.abs(p0v))


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_failed_frictional_step_is_one_line(monkeypatch):
    """A hyperelastic Coulomb step whose Newton iterations do not converge (here: allowed one) ends the run with
    one line naming the step and the residual (no Coulomb-bound hint: it is the linear step matrix's)."""
    monkeypatch.setattr(finite_strain_step, "MAX_IT", 1)
    with pytest.raises(StepError) as e:
        simulate("disc", {"level": 1, "vx0": 2000.0, "height": 0.05}, material="neo-hookean", friction="coulomb",
                 friction_options={"mu": 0.3}, dt=2.5e-4, T=0.01)
    assert "finite-strain Newton did not converge" in str(e.value) and "\n" not in str(e.value)


def _half_period(material, spec, T0):
    """The first return of the bowl disc's x-momentum to zero, from below (half a swing), over T0."""
    s = simulate(spec.problem(COMM, h=2.0), pair="P1+/P0", dt=T0 / 1000, T=0.6 * T0, material=material).timeseries
    t, px = np.asarray(s["t"]), np.asarray(s["momentum_x"])
    k = np.flatnonzero((px[:-1] < 0) & (px[1:] >= 0))[0]
    return (t[k] + (t[k + 1] - t[k]) * px[k] / (px[k] - px[k + 1])) / (T0 / 2)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_hyperelastic_disc_slides_in_a_bowl_with_the_pendulum_period():
    """demos/bowl_problem.py, frictionless (a curved obstacle: its rows linearised at U^n every step, solved by a
    gap-row Newton per tangent): the neo-Hookean disc translates on the circle of radius Rb - r, its half swing
    within 2 % of the small-angle pendulum's T0/2 (measured -1.2 % at h = 2 mm, dt = T0/1000) and within 0.5 %
    of the linear model's (measured 0.2 %: the disc does not turn, so both models are right)."""
    spec = load_file(Path(__file__).resolve().parents[2] / "demos" / "bowl_problem.py")
    T0 = spec.problem(COMM, h=2.0).parameters["period"]
    nh, lin = _half_period("neo-hookean", spec, T0), _half_period("linear", spec, T0)
    assert nh == pytest.approx(1.0, abs=0.02) and nh == pytest.approx(lin, rel=0.005)


def test_3d_friction_on_a_tilted_obstacle_is_friction_under_tilted_gravity(mpi_tmp_path):
    """The 3-D check (the friction cone in each node's frame): a neo-Hookean box (P1+/P0) on a plane tilted by 20
    degrees about the horizontal diagonal, Coulomb mu = 0.8 (12 vertices stick, 4 slip at the end), against the
    axis-aligned box under gravity R^T g: the same sets, the columns within 1e-7 of their scale and the friction
    force rotated by R within 1e-7 (measured 4e-9 and 8e-11; the Newton tolerance, as above). The rotated run
    writes its fields (the friction force's Cartesian components from the first row on)."""
    from test_obstacle_contact import _scale_diff
    from test_obstacle_friction import _box_on_slope
    kw = dict(pair="P1+/P0", dt=2e-5, T=2e-3, friction="coulomb", friction_options={"mu": 0.8}, material="neo-hookean")
    p0, R = _box_on_slope(20.0, False)
    p1, _ = _box_on_slope(20.0, True)
    s0, s1 = simulate(p0, **kw).timeseries, simulate(p1, out=mpi_tmp_path / "box", write_every=20, **kw).timeseries
    assert s0["n_stick"][-1] > 0 and s0["n_slip"][-1] > 0
    for c in ("n_active", "n_stick", "n_slip"):
        assert np.array_equal(s0[c], s1[c]), c
    for c in ("energy", "kinetic", "contact_force", "dissipated"):
        assert _scale_diff(s0[c], s1[c]) <= 1e-7, c
    f0 = np.vstack([s0["tangential_force_x"], s0["tangential_force_y"], np.zeros(len(s0["t"]))])
    f1 = np.vstack([s1["tangential_force_x"], s1["tangential_force_y"], s1["tangential_force_z"]])
    assert np.max(np.abs(R @ f0 - f1)) <= 1e-7 * np.max(np.abs(f0))
