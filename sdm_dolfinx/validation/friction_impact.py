"""The report's friction section, part 2: the disc's oblique impact with a sticking and a
sliding friction coefficient (not in the paper). Rank 0 only.

The contact stresses and the stick/slip status of every contact vertex are read from the
run's ``solution.xdmf`` (fields ``contact_stress``, ``tangential_stress`` and
``contact_status``: 0 free, 1 stick, 2 slip, at the vertices), written every few steps; the
impulses from the time series: the normal impulse J_N = P_y(T) - P_y(0) + m g T (the momentum
balance of the midpoint scheme, exact) and the change of horizontal velocity P_x / m.

Rigid-body impact theory (Coulomb, a disc with I = m R^2 / 2) gives what to compare with: the
contact point's tangential velocity vx - omega R falls by 3 mu J_N / m while it slides, so a disc
that slides through the whole impact (mu < vx0 m / (3 J_N)) loses dvx = -mu J_N / m, and one
that sticks ends rolling at vx = (2/3) vx0 (dvx = -vx0 / 3) if nothing reverses the slip.
"""
import math

import numpy as np

from sdm_dolfinx.validation.friction_rigid import discrete_mass
from sdm_dolfinx.validation.friction_study import IMPACT_MU
from sdm_dolfinx.study.series import Series
from sdm_dolfinx.study.entry import Entry, Verdict
from sdm_dolfinx.study.text import listing, pct
from sdm_dolfinx.study.plotting import pyplot, save
from sdm_dolfinx.io.xdmf_reader import read_xdmf

#: colours of the contact status (stick, slip)
STATUS_COLOURS = {1: "tab:blue", 2: "tab:red"}
#: Coulomb's cone checked at the stored vertices to this relative tolerance (round-off of the
#: semi-smooth Newton's converged multipliers)
CONE_RTOL = 1e-8

SAYS = {
    "friction_impact_stress": "Coulomb's law at the contact: the tangential stress stays in the cone |σ_T| ≤ μ σ_N, "
                              "on its boundary where the point slips (σ_T = −μ σ_N sign of the slip), inside where it "
                              "sticks. Rigid-body impact theory: a disc with I = m R²/2 slides through the whole "
                              "impact "
                              "when μ < vx0 m / (3 J_N) and then loses Δvx = −μ J_N / m; otherwise its contact point "
                              "stops slipping. Not in the paper.",
    "friction_impact_zones": "Stick and slip zones during an oblique impact (Cattaneo-Mindlin: with large friction the "
                             "centre of the contact zone sticks and its edges, where the normal stress is small, slip; "
                             "with small friction the whole zone slides). Not in the paper.",
}


def impact_frames(folder):
    """The contact vertices' state at every stored time of the run in ``folder``: ``times`` (s),
    and arrays (time, vertex) of the current position along the foundation ``x`` (mm),
    ``status``, ``normal`` and ``tangential`` stress (N/mm^2); ``a``: the column of point A
    (the lowest vertex at t = 0). Only vertices in contact at some stored time are kept."""
    series = read_xdmf(folder)
    verts = np.flatnonzero(series.vertex_mask())
    status = np.array([series.field("contact_status", t)[verts] for t in series.times])
    keep = verts[np.any(status > 0, axis=0)]
    status = status[:, np.any(status > 0, axis=0)]
    x0 = series.points[keep, 0]
    fields = {name: np.array([series.field(name, t)[keep] for t in series.times])
              for name in ("contact_stress", "tangential_stress")}
    ux = np.array([series.field("displacement", t)[keep, 0] for t in series.times])
    y0 = series.points[keep, 1]
    low = np.lexsort((np.abs(x0), np.round(y0, 9)))[0]
    return {"times": np.asarray(series.times), "x": x0[None, :] + ux, "status": status.astype(int),
            "normal": fields["contact_stress"], "tangential": fields["tangential_stress"], "a": int(low)}


def impact_measure(folder, frames):
    """Impulses, stick fraction and the cone's check of one impact run (see the module's docstring)."""
    s = Series(folder)
    p, o = s.info["problem"]["parameters"], s.info["run_options"]
    mu, m, g = o["mu"], discrete_mass(folder), p["gravity"]
    t = s.t
    on = np.flatnonzero(s["n_active"] > 0)
    jn = float((s["momentum_y"][-1] - s["momentum_y"][0]) / m + g * t[-1])
    dvx = float((s["momentum_x"][-1] - s["momentum_x"][0]) / m)
    stick, slip = float(np.sum(s["n_stick"])), float(np.sum(s["n_slip"]))
    act = frames["status"] > 0
    sn, st = frames["normal"][act], frames["tangential"][act]
    slipping = frames["status"][act] == 2
    ratio = np.abs(st) / np.maximum(mu * sn, 1e-300)
    a = frames["a"]
    on_a = frames["status"][:, a] > 0
    reversed_a = np.flatnonzero(on_a & (frames["tangential"][:, a] > 0))
    lam_file = frames["normal"][:, a]
    lam_ts = np.interp(frames["times"], t, s["lambda_probe"])
    return {"mu": mu, "vx0": p["vx0"], "level": p["level"], "dt": o["dt"], "write_every": o["write_every"],
            "contact_start": float(t[on[0]]), "contact_end": float(t[on[-1]]), "jn_over_m": jn, "dvx": dvx,
            "dvx_sliding_rigid": -mu * jn, "dvx_sticking_rigid": -p["vx0"] / 3.0,
            "mu_slides_throughout_below": p["vx0"] / (3.0 * jn),
            "stick_fraction": stick / max(stick + slip, 1.0), "max_active": int(s["n_active"].max()),
            "cone_max_ratio": float(ratio.max()) if ratio.size else math.nan,
            "cone_excess": float(ratio.max() - 1) if ratio.size else math.nan,
            "slip_off_cone": float(np.abs(ratio[slipping] - 1).max()) if slipping.any() else math.nan,
            "a_slip_fraction": float(np.mean(frames["status"][on_a, a] == 2)) if on_a.any() else math.nan,
            "a_tangential_positive_from": float(frames["times"][reversed_a[0]]) if len(reversed_a) else math.nan,
            **_slip_places(frames),
            "peak_normal_at_a": float(lam_file.max()),
            "peak_tangential_at_a": float(np.abs(frames["tangential"][:, a]).max()),
            "file_vs_timeseries_at_a": float(np.max(np.abs(lam_file - lam_ts)) / max(lam_ts.max(), 1e-300)),
            "energy_initial": float(s["energy"][0]), "energy_final": float(s["energy"][-1]),
            "dissipated": float(s["dissipated"][-1]), "wall_time": s.info.get("wall_time")}


def _slip_places(frames):
    """Where the vertices slip: the fraction of slipping vertex-times at an edge of the contact
    zone (the first or last vertex in contact along x), and slipping backward (sigma_T > 0)."""
    st, x, tang = frames["status"], frames["x"], frames["tangential"]
    edge = backward = total = 0
    for k in range(len(st)):
        act = np.flatnonzero(st[k] > 0)
        slip = np.flatnonzero(st[k] == 2)
        if not len(slip):
            continue
        ends = {act[np.argmin(x[k, act])], act[np.argmax(x[k, act])]}
        edge += sum(int(j in ends) for j in slip)
        backward += int(np.sum(tang[k, slip] > 0))
        total += len(slip)
    return {"slip_at_edge_fraction": edge / total if total else math.nan,
            "slip_backward_fraction": backward / total if total else math.nan}


def _fmt(meas, key, spec):
    """``meas[case][key]`` of every case, formatted."""
    return [format(m[key], spec) for m in meas.values()]


def _case_label(case, m):
    return f"{case}: μ = {m['mu']:g}"


def _window(frames, meas, margin=3e-4):
    """The stored times of the contact phase, with a margin (s)."""
    t = frames["times"]
    return (t >= meas["contact_start"] - margin) & (t <= meas["contact_end"] + margin)


def fig_impact_stress(out, data):
    """Normal and tangential contact stress at A over the contact phase, with Coulomb's cone."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(data), figsize=(7 * len(data), 4.6), sharey=True)
    for ax, (case, (frames, m)) in zip(np.atleast_1d(axes), data.items()):
        w = _window(frames, m)
        t, a = 1e3 * frames["times"][w], frames["a"]
        sn, st = frames["normal"][w, a], frames["tangential"][w, a]
        ax.fill_between(t, -m["mu"] * sn, m["mu"] * sn, color="0.9", label="Coulomb's cone |σ$_T$| ≤ μ σ$_N$")
        ax.plot(t, sn, ".-", color="tab:green", lw=1.4, ms=3, label="normal stress σ$_N$")
        ax.plot(t, st, ".-", color="tab:purple", lw=1.4, ms=3, label="tangential stress σ$_T$")
        slips = frames["status"][w, a] == 2
        ax.plot(t[slips], st[slips], "o", mfc="none", color="tab:red", ms=6, label="A slips")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set(xlabel="t (ms)", title=f"{_case_label(case, m)} ({pct(m['a_slip_fraction'], 2)} of A's contact "
                                      f"times slipping)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    np.atleast_1d(axes)[0].set_ylabel("contact stress at A (N/mm$^2$; σ$_T$ along +x)")
    first = next(iter(data.values()))[1]
    fig.suptitle(f"Friction: oblique impact of the disc (vx0 = {first['vx0']:g} mm/s, v0 = −1000 mm/s), P2/P1, "
                 f"midpoint, level {first['level']}, dt = {first['dt']:g} s: the stresses at A (lowest point)")
    fig.tight_layout()
    png = save(fig, out / "friction_impact_stress_A.png")
    meas = {case: m for case, (_, m) in data.items()}
    text, verdict = _stress_text(meas)
    return Entry("friction_impact_stress", text, verdict, says=SAYS["friction_impact_stress"], png=png, numbers=meas)


def _stress_text(meas):
    """The cone's check at every stored vertex and time, and the sliding case's impulse ratio:
    (sentence, verdict)."""
    slide, stick = meas["sliding"], meas["sticking"]
    cone = all(m["cone_max_ratio"] <= 1 + CONE_RTOL for m in meas.values())
    on_cone = all(m["slip_off_cone"] <= CONE_RTOL for m in meas.values() if not math.isnan(m["slip_off_cone"]))
    impulse = abs(slide["dvx"] / slide["dvx_sliding_rigid"] - 1)
    ok = cone and on_cone and impulse <= 0.01 and slide["a_slip_fraction"] == 1.0
    return (f"Ours: over every stored contact vertex and time, |σ_T| / (μ σ_N) − 1 is at most "
            f"{listing(_fmt(meas, 'cone_excess', '.1e'))} ({listing(meas)}), and at the "
            f"slipping vertices |σ_T| / (μ σ_N) differs from 1 by at most "
            f"{listing(_fmt(meas, 'slip_off_cone', '.1e'))} (on the cone). "
            f"At A the normal stress peaks at {listing(_fmt(meas, 'peak_normal_at_a', '.1f'))} N/mm² "
            f"and |σ_T| at {listing(_fmt(meas, 'peak_tangential_at_a', '.1f'))} N/mm²; A slips at "
            f"{pct(slide['a_slip_fraction'], 3)} of its contact times for μ = {slide['mu']:g} and "
            f"{pct(stick['a_slip_fraction'], 2)} for μ = {stick['mu']:g}. Sliding case: J_N / m = "
            f"{slide['jn_over_m']:.0f} mm/s (rigid theory: it slides throughout since μ < "
            f"{slide['mu_slides_throughout_below']:.3f}), "
            f"Δvx = {slide['dvx']:.1f} mm/s against −μ J_N / m = {slide['dvx_sliding_rigid']:.1f} "
            f"({pct(slide['dvx'] / slide['dvx_sliding_rigid'] - 1, 2)}). The file's σ_N at A equals the time series' "
            f"lambda_probe to {max(m['file_vs_timeseries_at_a'] for m in meas.values()):.1e} (relative to its peak). ",
            Verdict.of(ok, cone))


def fig_impact_zones(out, data):
    """Stick and slip zones along the foundation over the contact phase, one panel per case."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(data), figsize=(7 * len(data), 4.8), sharey=True)
    for ax, (case, (frames, m)) in zip(np.atleast_1d(axes), data.items()):
        w = _window(frames, m)
        t = 1e3 * frames["times"][w]
        st, x = frames["status"][w], frames["x"][w]
        for code, name in ((1, "stick"), (2, "slip")):
            i, j = np.nonzero(st == code)
            ax.scatter(t[i], x[i, j], s=10, marker="s", color=STATUS_COLOURS[code], lw=0, label=name)
        ax.plot(t, x[:, frames["a"]], "k-", lw=0.7, label="point A")
        ax.set(xlabel="t (ms)", title=f"{_case_label(case, m)}: {pct(m['stick_fraction'], 2)} of the contact "
                                      "vertex-steps stick")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left", markerscale=1.5)
    np.atleast_1d(axes)[0].set_ylabel("position along the foundation, x + u$_x$ (mm)")
    first = next(iter(data.values()))[1]
    fig.suptitle(f"Friction: stick (blue) and slip (red) at the contact vertices during the oblique impact "
                 f"(vx0 = {first['vx0']:g} mm/s), level {first['level']}, fields every "
                 f"{first['dt'] * first['write_every']:g} s")
    fig.tight_layout()
    png = save(fig, out / "friction_impact_zones.png")
    meas = {case: m for case, (_, m) in data.items()}
    text, verdict = _zones_text(meas)
    return Entry("friction_impact_zones", text, verdict, says=SAYS["friction_impact_zones"], png=png, numbers=meas)


def _zones_text(meas):
    """Stick fractions, where the sticking case slips, against rigid theory; the energy dissipated:
    (sentence, verdict)."""
    slide, stick = meas["sliding"], meas["sticking"]
    ok = slide["stick_fraction"] == 0.0 and stick["stick_fraction"] >= 0.75
    rev = stick["a_tangential_positive_from"]
    return (f"Ours: contact from {1e3 * stick['contact_start']:.2f} to {1e3 * stick['contact_end']:.2f} ms, at most "
            f"{stick['max_active']} vertices at once. μ = {slide['mu']:g}: {pct(slide['stick_fraction'], 2)} of the "
            f"contact vertex-steps stick (the whole zone slides forward). μ = {stick['mu']:g}: "
            f"{pct(stick['stick_fraction'], 2)} stick; of the vertex-steps that slip, "
            f"{pct(stick['slip_at_edge_fraction'], 2)} "
            f"are at an edge of the contact zone and {pct(stick['slip_backward_fraction'], 2)} slip backward "
            f"(σ_T > 0)" + ("" if math.isnan(rev) else f"; at A the tangential stress turns positive at "
                            f"{1e3 * rev:.2f} ms") + ": the contact ends slipping backward, the disc spinning faster "
            f"than rolling. It "
            f"loses Δvx = {stick['dvx']:.0f} mm/s against {stick['dvx_sticking_rigid']:.0f} for a rigid disc that ends "
            f"rolling: the elastic disc's stuck contact keeps braking it while its tangential deformation grows. "
            f"Friction "
            f"dissipates {listing(pct(m['dissipated'] / m['energy_initial'], 2) for m in meas.values())} of the "
            f"energy ({listing(meas)}). Criterion: the sliding case never sticks, the sticking case sticks at "
            f"≥ 75 % of its vertex-steps. ", Verdict.of(ok, stick["stick_fraction"] > slide["stick_fraction"]))


def impact_entries(fs, runs_dir, out):
    """Both impact figures from one reading of the runs' files."""
    data = {}
    for case in IMPACT_MU:
        folder = runs_dir / fs.impact[case].name
        frames = impact_frames(folder)
        data[case] = (frames, impact_measure(folder, frames))
    return [fig_impact_stress(out, data), fig_impact_zones(out, data)]
