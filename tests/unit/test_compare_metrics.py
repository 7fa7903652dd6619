"""The comparison's metrics (sdm_dolfinx.post.metrics) and its tables (paper.compare_table),
each on a case whose answer is known in closed form: synthetic time series, and exact solutions
interpolated on meshes (zero error where the metric compares with the interpolant, the
interpolation error at its known rate where it compares with a finer one)."""
import math
from types import SimpleNamespace

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.compare import table as ct
from sdm_dolfinx.post import metrics as cm
from sdm_dolfinx.run.observe import State

COMM = MPI.COMM_WORLD


# ----------------------------------------------------------------------------- time series
def test_energy_errors_and_penetration():
    eT, emax = cm.energy_errors([2.0, 2.2, 1.8, 2.1])
    assert eT == pytest.approx(0.05, rel=1e-14) and emax == pytest.approx(0.1, rel=1e-14)
    assert cm.energy_errors([1.0, np.inf]) == (math.inf, math.inf)
    assert cm.max_penetration([0.1, -0.2, 0.05, np.inf]) == pytest.approx(0.2)
    assert cm.max_penetration([0.1, 0.0]) == 0.0 and cm.max_penetration([]) == 0.0


def test_l2_time_error_of_a_constant_offset():
    """values = e + d on [0, pi], e = sin t: the relative error is d sqrt(pi) / sqrt(pi / 2) = d sqrt(2)
    (rectangle rule on N + 1 samples: to O(dt))."""
    t = np.linspace(0.0, np.pi, 2001)
    e = np.sin(t)
    assert cm.l2_time_error(t, e, e) == 0.0
    d = 1e-3
    assert cm.l2_time_error(t, e + d, e) == pytest.approx(d * math.sqrt(2.0), rel=2e-3)
    assert cm.l2_time_error(t, 0 * t + d, 0 * t) == pytest.approx(d * math.sqrt(np.pi), rel=2e-3)


def test_linf_relative_and_velocity():
    assert cm.linf_relative([0.1, 0.3, 0.2], [1.0, 2.0, 3.0]) == pytest.approx(0.1)
    t = np.linspace(0.0, 1.0, 101)
    v = cm.velocity_of(t, t ** 2)             # backward differences of t^2: 2 t - dt
    assert np.allclose(v[1:], 2 * t[1:] - 0.01, atol=1e-12)


def _rod_stress(t):
    """The rod's exact contact stress: 1/2 on [1, 2), else 0."""
    t = np.asarray(t, dtype=float)
    return np.where((t >= 1.0) & (t < 2.0), 0.5, 0.0)


def test_oscillation_index_counts_spurious_oscillations():
    """TV over the widened contact phase: the exact stress's is 1 (up 1/2, down 1/2); n full sine periods
    of amplitude a added inside the phase add 4 n a; a smooth rise and fall without overshoot gives 1."""
    t = np.linspace(0.0, 3.0, 30001)
    s = _rod_stress(t)
    iv = [(1.0, 2.0)]
    assert cm.oscillation_index(t, s, s, iv) == pytest.approx(1.0, rel=1e-12)
    a, n = 0.05, 7
    osc = s + np.where(s > 0, a * np.sin(2 * np.pi * n * (t - 1.0)), 0.0)
    assert cm.oscillation_index(t, osc, s, iv) == pytest.approx(1.0 + 4 * n * a, rel=1e-3)
    smooth = 0.5 * np.clip(np.minimum(t - 0.9, 2.1 - t) / 0.2, 0.0, 1.0)
    assert cm.oscillation_index(t, smooth, s, iv) == pytest.approx(1.0, rel=1e-12)


def test_release_time_error_and_contact_intervals():
    """A stress released d late has the release error d (to one sample); a contact that never happens
    is an infinite error; contact intervals are read back from a sampled stress."""
    dt = 1e-3
    t = np.arange(0, 6001) * dt
    iv = [(1.0, 2.0), (4.0, 5.0)]
    s = _rod_stress(t) + _rod_stress(t - 3.0)
    assert cm.release_time_error(t, s, iv, 0.005) <= dt + 1e-12
    d = 0.05
    late = np.where((t >= 1.0) & (t < 2.0 + d), 0.5, 0.0) + _rod_stress(t - 3.0)
    assert cm.release_time_error(t, late, iv, 0.005) == pytest.approx(d, abs=1.5 * dt)
    assert cm.release_time_error(t, 0 * t, iv, 0.005) == math.inf
    found = cm.contact_intervals_of(t, s, 0.005)
    assert np.allclose(found, iv, atol=1.5 * dt)


def test_series_metrics_of_the_exact_series():
    """A run that reproduces the exact samples has zero errors, oscillation index 1 and a release error of
    at most one step; its costs are read from run.json."""
    dt = 2e-3
    t = np.arange(0, 1501) * dt
    u = lambda s: np.where(np.asarray(s) < 1.0, 0.5 - 0.5 * np.asarray(s), 0.0)   # noqa: E731
    truth = {"u": u, "s": _rod_stress, "intervals": [(1.0, 2.0)]}
    ts = {"t": t, "energy": np.full(t.size, 0.125), "u_probe": u(t), "lambda_probe": _rod_stress(t),
          "newton_its": np.r_[0, np.full(t.size - 1, 2.0)], "gap_min_boundary": u(t)}
    info = {"steps": t.size - 1, "wall_time": 4.0, "setup_time": 1.0}
    m = cm.series_metrics(ts, info, truth)
    assert m["energy_error_T"] == 0 and m["energy_error_max"] == 0
    assert m["u_contact_L2t"] == 0 and m["stress_contact_L2t"] == 0 and m["v_contact_L2t"] == 0
    assert m["oscillation_index"] == pytest.approx(1.0) and m["release_time_error"] <= dt + 1e-12
    assert m["penetration_max"] == 0 and m["newton_per_step"] == 2.0
    assert m["wall_per_step"] == pytest.approx(3.0 / 1500)
    assert set(m) - {"undefined"} <= set(cm.METRICS) and m["undefined"] == {}


def test_a_metric_against_a_zero_reference_is_not_defined():
    """Before the rod's first contact (T = 0.5 < 1) the exact stress is 0: the contact-phase metrics are
    not defined (nan, with the reason), not "0 for everybody"; a reference displacement at the contact
    point that is zero to round-off against the reference's own scale is not defined either, whatever
    the judged run did (it came out as 1e13); with no scale only an exact zero counts."""
    dt = 2e-3
    t = np.arange(0, 251) * dt
    u = lambda s: 0.5 - 0.5 * np.asarray(s)                                  # noqa: E731
    truth = {"u": u, "s": _rod_stress, "intervals": [(1.0, 2.0)], "what": "the exact solution"}
    ts = {"t": t, "energy": np.full(t.size, 0.125), "u_probe": u(t) + 1e-3, "lambda_probe": np.zeros(t.size),
          "newton_its": np.ones(t.size)}
    m = cm.series_metrics(ts, {"steps": 250}, truth)
    assert set(m["undefined"]) == set(cm.CONTACT_PHASE)
    assert all("no contact in [0, 0.5]" in why for why in m["undefined"].values())
    assert all(math.isnan(m[k]) for k in cm.CONTACT_PHASE) and m["u_contact_L2t"] > 0
    still = {"u": lambda s: np.full(np.size(s), 1e-20), "s": lambda s: np.ones(np.size(s)), "intervals": [(0.0, 2.0)],
             "what": "the reference run", "u_scale": 0.5}
    for u_probe in (np.zeros(t.size), np.full(t.size, 1e3)):                 # a good run and a wild one
        m = cm.series_metrics({**ts, "u_probe": u_probe}, {"steps": 250}, still)
        assert "zero to round-off" in m["undefined"]["u_contact_L2t"] and math.isnan(m["u_contact_L2t"])
        assert "v_contact_L2t" in m["undefined"] and "stress_contact_L2t" not in m["undefined"]
    m = cm.series_metrics(ts, {"steps": 250}, {**still, "u_scale": None})
    assert "u_contact_L2t" not in m["undefined"] and m["u_contact_L2t"] > 1e10      # no scale: defined


def test_the_ranking_leaves_undefined_metrics_out_and_says_why():
    """Metrics not defined for the window are shown as n/d, ranked by nobody, counted out of the mean
    rank, and a window without contact is said in the ranking's text."""
    base = {"h": 0.1, "dt": 0.05, "status": "finished"}
    why = {k: "no contact in [0, 0.5] (the exact solution)" for k in cm.CONTACT_PHASE}
    recs = [{**base, "method": "a", **{k: 1.0 for k in ct.RANKED}, "undefined": why},
            {**base, "method": "b", **{k: 2.0 for k in ct.RANKED}, "undefined": why}]
    for r in recs:
        r.update({k: math.nan for k in why})
    r = ct.ranking(recs)
    assert not any(k in r["methods"][m]["ranks"] for m in "ab" for k in cm.CONTACT_PHASE)
    assert r["ranked"] == [k for k in ct.RANKED if k not in cm.CONTACT_PHASE] and r["order"] == ["a", "b"]
    header, rows = ct.table_rows(r, {})
    assert rows[0][header.index("stress_contact_L2t")] == "n/d"
    text = ct.markdown(r, {}, "t")
    assert f"over the {len(ct.RANKED) - 3} accuracy metrics defined here" in text
    assert "This comparison has no contact in [0, 0.5]" in text and "Not defined (not ranked):" in text


# ----------------------------------------------------------------------------- field errors
class _GapState(State):
    """A State whose gaps are given (-0.25 at the vertices, none on the boundary)."""

    def vertex_gap(self):
        return -0.25

    def boundary_gap(self):
        return np.inf


def _state(u, t, shape=(), component=None):
    """The observed State of the Function ``u`` at time ``t`` (a Discretisation with what
    FieldErrors reads)."""
    V = u.function_space
    problem = SimpleNamespace(mesh=V.mesh, shape=shape, constraint_component=component)
    d = SimpleNamespace(W=V, comm=V.mesh.comm, problem=problem)
    return _GapState(0, t, compat.petsc_vec(u).array_r, None, np.zeros(0), d)


class _SineExact:
    """u = sin(pi x) cos(t) on [0, 1]."""

    def displacement(self, x, t):
        return np.sin(np.pi * x[0]) * np.cos(t)


def _observe(N, degree, raise_degree, t_state, t_exact):
    msh = dmesh.create_interval(COMM, N, [0.0, 1.0])
    V = compat.function_space(msh, compat.element("Lagrange", "interval", degree))
    u = fem.Function(V)
    u.interpolate(lambda x: _SineExact().displacement(x, t_state))
    obs = cm.FieldErrors(_SineExact(), raise_degree)
    obs(_state(u, t_exact))
    return obs.table()


def test_field_errors_of_the_interpolant():
    """GetFEM's convention (the error against the interpolant in W^h): the interpolant itself has zero
    error; a state at t + d has the error |cos(t + d) - cos t| ||sin(pi x)|| = |...| / sqrt(2); the norm
    columns are the interpolant's; the gap is the state's."""
    r = _observe(64, 1, 0, 0.3, 0.3)
    assert r["err_L2"][0] < 1e-14 and r["err_H1"][0] < 1e-13 and r["gap"][0] == -0.25
    assert r["norm_L2"][0] == pytest.approx(math.cos(0.3) / math.sqrt(2), rel=1e-3)
    d = 0.01
    r = _observe(64, 1, 0, 0.3 + d, 0.3)
    assert r["err_L2"][0] == pytest.approx(abs(math.cos(0.3 + d) - math.cos(0.3)) / math.sqrt(2), rel=1e-3)


@pytest.mark.parametrize("degree", [1, 2])
def test_field_errors_against_a_finer_interpolant_fall_at_the_interpolation_rate(degree):
    """Against u interpolated two degrees higher, the interpolant's error is the interpolation error:
    rate degree + 1 in L2 and degree in H1 (the H1 error is dominated by the gradient's)."""
    Ns = [8, 16, 32]
    rows = [_observe(N, degree, 2, 0.0, 0.0) for N in Ns]
    h = 1.0 / np.array(Ns)
    rL2 = np.polyfit(np.log(h), np.log([r["err_L2"][0] for r in rows]), 1)[0]
    rH1 = np.polyfit(np.log(h), np.log([r["err_H1"][0] for r in rows]), 1)[0]
    assert rL2 == pytest.approx(degree + 1, abs=0.1) and rH1 == pytest.approx(degree, abs=0.1)


def test_field_errors_of_the_rods_kinked_solution_fall_at_the_rates_of_a_kink():
    """The rod's closed form at t = 1/3 has a kink at x = 1/3, never a node of the meshes N = 2^k (it lies
    1/3 or 2/3 into its cell): the P1 interpolant's error is confined to that cell, O(h^1.5) in L2 and
    O(h^0.5) in H1, against the cubic interpolant as against u; the interpolant itself has zero error."""
    from sdm_dolfinx.problems.rod1d import RodExact
    Ns, errs = [16, 32, 64, 128], []
    for N in Ns:
        msh = dmesh.create_interval(COMM, N, [0.0, 1.0])
        V = compat.function_space(msh, compat.element("Lagrange", "interval", 1))
        u = fem.Function(V)
        u.interpolate(lambda x: RodExact().displacement(x, 1 / 3))
        obs, gl = cm.FieldErrors(RodExact(), 2), cm.FieldErrors(RodExact())
        for o in (obs, gl):
            o(_state(u, 1 / 3))
        assert gl.table()["err_H1"][0] < 1e-14
        errs.append((obs.table()["err_L2"][0], obs.table()["err_H1"][0]))
    h = 1.0 / np.array(Ns)
    rL2, rH1 = (np.polyfit(np.log(h), np.log([e[k] for e in errs]), 1)[0] for k in (0, 1))
    assert rL2 == pytest.approx(1.5, abs=0.1) and rH1 == pytest.approx(0.5, abs=0.1)


def test_field_errors_of_a_vector_field_put_a_scalar_exact_in_the_constrained_component():
    """A 2-D vector field whose exact solution gives the constrained component only (u_y = x y): the
    interpolant has zero error and ||u|| = ||x y||_{L2(unit square)} = 1/3."""
    msh = dmesh.create_unit_square(COMM, 6, 6)
    V = compat.function_space(msh, compat.element("Lagrange", "triangle", 2, (2,)))
    exact = SimpleNamespace(displacement=lambda x, t: x[0] * x[1])
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([0 * x[0], x[0] * x[1]]))
    obs = cm.FieldErrors(exact)
    obs(_state(u, 0.0, (2,), 1))
    r = obs.table()
    assert r["err_H1"][0] < 1e-13
    assert r["norm_L2"][0] == pytest.approx(1.0 / 3.0, rel=1e-12)
    assert obs.csv_text().splitlines()[0] == ",".join(cm.FieldErrors.COLUMNS)


# ----------------------------------------------------------------------------- rates and ranking
def test_fit_rate_recovers_a_power_law_along_the_longest_path():
    pts = [(h, 0.5 * h, 3.0 * h ** 2) for h in (0.1, 0.05, 0.025)] + [(0.1, 0.01, 1.0)]
    fit = ct.fit_rate(pts)
    assert fit["rate"] == pytest.approx(2.0, abs=1e-12) and fit["kind"] == "dt/h fixed"
    assert ct.fit_rate([(0.1, 0.05, 1.0)]) is None
    fixed_dt = ct.fit_rate([(h, 0.01, h ** 1.5) for h in (0.1, 0.05)])
    assert fixed_dt["rate"] == pytest.approx(1.5, abs=1e-12) and fixed_dt["kind"] == "h at fixed dt"


def test_ranking_orders_by_value_and_puts_blow_ups_last():
    base = {"h": 0.1, "dt": 0.05}
    recs = [{**base, "method": "a", "status": "finished", **{k: 1.0 for k in ct.RANKED}},
            {**base, "method": "b", "status": "finished", **{k: 2.0 for k in ct.RANKED}},
            {**base, "method": "c", "status": "failed", "energy_error_max": 5.0},
            {**base, "method": "d", "status": "refused", "reason": "no"},
            {"h": 0.2, "dt": 0.1, "method": "a", "status": "finished", "u_LinfL2": 4.0}]
    r = ct.ranking(recs)
    assert (r["h"], r["dt"]) == (0.1, 0.05) and r["order"] == ["a", "b", "c", "d"]
    assert r["methods"]["c"]["ranks"]["u_LinfL2"] == 3            # failed: inf, last
    assert r["methods"]["c"]["ranks"]["energy_error_max"] == 3     # 5 > 2 > 1
    recs[1]["penetration_max"], recs[0]["penetration_max"] = 1e-16, 0.0      # round-off ties
    recs[1]["u_LinfL2"] = 1.0004                                               # equal to 3 digits: ties
    r = ct.ranking(recs)
    assert r["methods"]["b"]["ranks"]["penetration_max"] == r["methods"]["a"]["ranks"]["penetration_max"] == 1
    assert r["methods"]["b"]["ranks"]["u_LinfL2"] == 1 and r["methods"]["c"]["ranks"]["u_LinfL2"] == 3
    header, rows = ct.table_rows(r, ct.rates(recs))
    assert rows[-1][3].startswith("refused") and len(rows[0]) == len(header)
    assert ct.rates(recs)["a"]["u_LinfL2"]["rate"] == pytest.approx(2.0)     # 1 at h = 0.1, 4 at 0.2
