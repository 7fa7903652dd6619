"""The report's friction section (not in the paper), part 1: the disc rolling and
sliding down the incline, and the block sliding to a stop, against their rigid-body closed
forms (:func:`sdm_dolfinx.problems.disc.incline_motion`, :func:`sdm_dolfinx.problems.block.stopping`).
The oblique impact is :mod:`.friction_impact`. Each figure returns a report
:class:`~sdm_dolfinx.study.entry.Entry` (its ``says``: what the closed form says); rank 0 only.

What is measured, from the time series alone (P_x = e_x^T M Vbar, the column ``momentum_x``,
which the midpoint scheme changes by exactly dt (m g sin theta + sum lam_T) per step; m = e^T M e
the discrete mass, the problem rebuilt from run.json):

* the disc's mean acceleration over the run, P_x(T) / (m T), and a fitted one
  (:func:`incline_measure`): sliding, the slope of P_x / m once the contact slips; rolling, the
  line of :func:`oscillation_fit` (the rigid motion plus the elastic disc's oscillation on its
  tangential contact stiffness);
* the slip of point A (``slip_probe``: its displacement increment along the foundation per
  step): its acceleration, a line fitted to slip / dt while sliding (rigid disc:
  g (sin theta - 3 mu cos theta));
* the block's velocity P_x / m, its deceleration (a line fitted while 10 % < v / v0 < 90 %) and
  its stop time (the first zero of v, interpolated between steps).
"""
import math

from mpi4py import MPI

import numpy as np

from dolfinx import fem

from sdm_dolfinx import compat, problems
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.validation.friction_study import BLOCK_MU, INCLINE_MU, INCLINE_T, THETA, block_threshold
from sdm_dolfinx.study.series import Series
from sdm_dolfinx.study.entry import Entry, Verdict
from sdm_dolfinx.study.text import html_table, listing, pct
from sdm_dolfinx.study.plotting import COLOURS, pyplot, save
from sdm_dolfinx.problems import block as block_problem, disc as disc_problem

#: the verdicts' tolerances (rigid closed forms against an elastic body): the incline's fitted
#: accelerations at every level, rolling (about one period of the disc's tangential oscillation in
#: the run, and slip at the contact zone's edges at level 3: measured 1.1, 0.04, 2.3 % on levels
#: 1-3) and sliding (measured <= 0.006 %), and the block's stop time (its bottom rings at ~1.6 ms
#: periods; one step is 0.3 % of the stop: measured 0.29 % Coulomb, 0.014 % Tresca)
ROLL_TOL, SLIDE_TOL, BLOCK_TOL = 0.03, 0.001, 0.02

_ROLL = disc_problem.incline_motion(9810.0, THETA, INCLINE_MU["rolling"], 20.0)
_STOP = block_problem.stopping(100.0, 9810.0, 2e-4, 20.0, mu=BLOCK_MU)
SAYS = {
    "friction_incline": f"Closed form (rigid disc, I = m R²/2, on an incline at θ = {THETA:g}°): with Coulomb "
                        f"friction μ ≥ tan θ / 3 = {_ROLL['mu_roll']:.3f} it rolls without slipping, its centre "
                        f"accelerating at (2/3) g sin θ = {_ROLL['a']:.0f} mm/s² (g = 9810 mm/s²); with μ < tan θ / 3 "
                        "it slides, a = g (sin θ − μ cos θ), and its contact point slips at g (sin θ − 3 μ cos θ) "
                        "(docs/friction_problems.md). Not in the paper.",
    "friction_block": f"Closed form (rigid block, m = 2e-4 t/mm, v0 = 100 mm/s): Coulomb friction μ = {BLOCK_MU:g} "
                      f"decelerates it at μ g and stops it at t* = v0 / (μ g) = {1e3 * _STOP[1]:.1f} ms; a Tresca "
                      "threshold s "
                      f"(here {block_threshold():g} N/mm², s L = μ m g) decelerates it at s L / m: the same stop. "
                      "Not in the paper.",
}


def discrete_mass(folder):
    """e^T M e = rho |Omega_h| (t per mm) of the run in ``folder``, its problem rebuilt from run.json."""
    info = Series(folder).info
    return disc_problem.total_mass(problems.rebuild(info["problem"], MPI.COMM_SELF))


def discrete_inertia(folder):
    """The discrete disc's mass and moment of inertia about its centre, (e^T M e, r^T M r) with
    e = e_x and r(x) = e_z x (x - centre) the unit rotation, M the run's mass matrix (rebuilt from
    run.json; P2/P1: B^T C^-1 B with the lumped C of the P1 velocities, whose rotational inertia
    is below m R^2 / 2 by O(h^2))."""
    info = Series(folder).info
    problem = problems.rebuild(info["problem"], MPI.COMM_SELF)
    opts = info["run_options"]
    d = Discretisation(problem, opts["pair"], mass=opts.get("mass"), quadrature_degree=opts.get("quadrature_degree"))
    xc, yc = problem.parameters["centre"]
    f = fem.Function(d.W)
    f.interpolate(lambda x: np.vstack([-(x[1] - yc), x[0] - xc]))
    out = []
    for v in (d.rigid_vector(0), compat.petsc_vec(f)):
        y = v.duplicate()
        d.mass_mult(v, y)
        out.append(float(v.dot(y)))
    return tuple(out)


# ------------------------------------------------------------------------------ the incline
def oscillation_fit(t, v, shortest=2e-3):
    """Fit v(t) = a t + c + A sin(w t) + B cos(w t): the rigid motion's constant acceleration
    plus one oscillation (linear least squares for a, c, A, B; w by a scan of periods from
    ``shortest`` to 3 T, then refined). Returns ``(a, period, amplitude, rms residual)``."""
    from scipy.optimize import minimize_scalar

    def solve(w):
        X = np.column_stack([t, np.ones_like(t), np.sin(w * t), np.cos(w * t)])
        c = np.linalg.lstsq(X, v, rcond=None)[0]
        return float(np.sum((X @ c - v) ** 2)), c

    ws = 2 * np.pi / np.linspace(shortest, 3 * t[-1], 300)
    k = int(np.argmin([solve(w)[0] for w in ws]))
    lo, hi = sorted((ws[min(k + 1, len(ws) - 1)], ws[max(k - 1, 0)]))
    w = minimize_scalar(lambda x: solve(x)[0], bounds=(lo, hi), method="bounded", options={"xatol": 1e-9}).x
    r, c = solve(w)
    return float(c[0]), float(2 * np.pi / w), float(np.hypot(c[2], c[3])), float(np.sqrt(r / len(t)))


def _slipping_window(s):
    """The steps after the initial stick (from the first step at which every active vertex slips)."""
    sliding = (s["n_slip"] > 0) & (s["n_stick"] == 0)
    return np.arange(len(s.t)) >= (int(np.argmax(sliding)) if sliding.any() else len(s.t))


def incline_measure(folder):
    """The incline run's accelerations, measured and closed form.

    The mean acceleration (P_x(T) - P_x(0)) / (m T), and the fitted one: sliding, the slope of
    P_x / m once A slips (after the elastic disc's first steps of stick, while the friction force
    builds up to mu N); rolling, the line of :func:`oscillation_fit` (the disc starts without the
    tangential force m g sin(theta) / 3 of steady rolling, so it oscillates about the rolling
    motion on its tangential contact stiffness: amplitude F / (m w) for an undamped mode).
    """
    s = Series(folder)
    p, o = s.info["problem"]["parameters"], s.info["run_options"]
    g, mu, th = p["gravity"], o["mu"], math.radians(THETA)
    m, inertia = discrete_inertia(folder)
    t, v, after = s.t, s["momentum_x"] / m, s.t > 0
    closed = disc_problem.incline_motion(g, THETA, mu, p["radius"])
    out = {"level": p["level"], "h": p["h"], "dt": o["dt"], "dofs": s.info.get("dim_W"), "mu": mu,
           "regime": closed["regime"], "a_closed": closed["a"], "a_mean": float(v[-1] / t[-1]),
           "steps": int(np.sum(after)), "steps_slipping": int(np.sum(s["n_slip"][after] > 0)),
           "steps_sticking": int(np.sum(s["n_stick"][after] > 0)), "start": p.get("start", "unstressed"),
           "max_slipping": int(s["n_slip"].max()), "max_active": int(s["n_active"].max()),
           "normal_force_range": [float(x / (m * g * math.cos(th))) for x in
                                  (s["contact_force"][after].min(), s["contact_force"][after].max())],
           "mass": m, "wall_time": s.info.get("wall_time")}
    if closed["regime"] == "rolling":
        a, period, amp, rms = oscillation_fit(t, v)
        out.update(a=a, period=period, amplitude=amp, amplitude_predicted=g * math.sin(th) / 3 * period / (2 * np.pi),
                   fit_rms=rms, inertia_error=inertia / (0.5 * m * p["radius"] ** 2) - 1.0,
                   a_discrete_inertia=g * math.sin(th) / (1.0 + inertia / (m * p["radius"] ** 2)))
        out["discrete_inertia_rel"] = out["a_discrete_inertia"] / closed["a"] - 1.0
    else:
        w = _slipping_window(s)
        slip_rate = s["slip_probe"][w] / o["dt"]
        out.update(a=float(np.polyfit(t[w], v[w], 1)[0]), stick_until=float(t[w][0]),
                   all_slip_after_onset=bool(np.all((s["n_slip"][w] > 0) & (s["n_stick"][w] == 0))),
                   slip_acc=float(np.polyfit(t[w], slip_rate, 1)[0]),
                   slip_acc_closed=g * (math.sin(th) - 3 * mu * math.cos(th)))
    out["rel_error"] = out["a"] / closed["a"] - 1.0
    out["mean_rel_error"] = out["a_mean"] / closed["a"] - 1.0
    return out


def fig_incline(fs, runs_dir, out):
    """The centre's velocity against the closed forms, its deviation from them at every level,
    and the relative error of the acceleration against h (log-log); with a table."""
    meas = {reg: {lev: incline_measure(runs_dir / r.name) for lev, r in sorted(by.items())}
            for reg, by in fs.incline.items()}
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(17, 4.8))
    for k, (reg, by) in enumerate(meas.items()):
        for j, lev in enumerate(by):
            s, m = Series(runs_dir / fs.incline[reg][lev].name), by[lev]
            v = s["momentum_x"] / m["mass"]
            if lev == max(by):
                axes[0].plot(1e3 * s.t, v, color=COLOURS[k], lw=2.0, label=f"{reg}, μ = {m['mu']:g}: ours, level {lev}")
                axes[0].plot(1e3 * s.t, m["a_closed"] * s.t, "k--", lw=0.9)
            axes[1].plot(1e3 * s.t, v - m["a_closed"] * s.t, color=COLOURS[k], ls=("-", "--", ":")[j % 3],
                         label=f"{reg}, level {lev}")
        hh = [by[lev]["h"] for lev in by]
        axes[2].loglog(hh, [abs(by[lev]["rel_error"]) for lev in by], "o-", color=COLOURS[k],
                       label=f"{reg}: fitted acceleration")
        axes[2].loglog(hh, [abs(by[lev]["mean_rel_error"]) for lev in by], "s:", color=COLOURS[k], mfc="none",
                       label=f"{reg}: mean acceleration over the run")
        if reg == "rolling":
            axes[2].loglog(hh, [abs(by[lev]["discrete_inertia_rel"]) for lev in by], "k^--", lw=0.9,
                           label="rigid disc with the discrete inertia r$^T$M r")
    t = np.linspace(0.0, INCLINE_T, 50)
    g_sin = next(iter(meas.values()))[1]["a_closed"] * 1.5              # (2/3) g sin theta -> g sin theta
    axes[0].plot(1e3 * t, g_sin * t, color="0.6", lw=1.0, label="frictionless: g sin θ t")
    axes[0].plot([], [], "k--", lw=0.9, label="closed forms (rigid disc)")
    axes[0].set(xlabel="t (ms)", ylabel="P$_x$ / m (mm/s)", title="velocity of the centre of mass (x down the slope)")
    axes[1].set(xlabel="t (ms)", ylabel="P$_x$ / m − a$_{closed}$ t (mm/s)", title="deviation from the closed form")
    axes[2].set(xlabel="gmsh mesh size h (mm); dt halved with h", ylabel="|a / a$_{closed}$ − 1|",
                title=f"relative error of the acceleration ({1e3 * INCLINE_T:g} ms)")
    low = min(abs(m["rel_error"]) for by in meas.values() for m in by.values())
    axes[2].set_ylim(max(low, 1e-12) / 30, 0.1)          # room below the curves for the legend
    for ax, where in zip(axes, ("upper left", "upper right", "lower center")):
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7 if ax is axes[2] else 8, loc=where, ncol=2 if ax is axes[2] else 1)
    fig.suptitle(f"Friction: the disc rolling (μ ≥ tan θ / 3) and sliding (μ < tan θ / 3) down a {THETA:g}° incline, "
                 "P2/P1, midpoint, Coulomb")
    fig.tight_layout()
    png = save(fig, out / "friction_incline.png")
    text, verdict = _incline_text(meas)
    return Entry("friction_incline", text, verdict, says=SAYS["friction_incline"], png=png,
                 html=_incline_table(meas), numbers=meas)


def _incline_text(meas):
    """The incline's sentence and verdict: the errors at every level, the regimes, the oscillation and
    the slip."""
    roll, slide = meas["rolling"], meas["sliding"]
    r, sl = roll[max(roll)], slide[max(slide)]
    levels = ("levels " if len(roll) > 1 else "level ") + listing(str(lev) for lev in sorted(roll))
    err = lambda by, key="rel_error": listing(pct(by[lev][key], 2) for lev in sorted(by))     # noqa: E731
    roll_ok = all(abs(x["rel_error"]) <= ROLL_TOL and x["steps_slipping"] < x["steps"] for x in roll.values())
    slide_ok = all(abs(x["rel_error"]) <= SLIDE_TOL and x["all_slip_after_onset"] for x in slide.values())
    errs = [abs(roll[lev]["rel_error"]) for lev in sorted(roll)]
    trend = ("" if len(errs) < 2 else " It decreases with h." if all(np.diff(errs) < 0) else
             " Fitted over about one period, the error does not decrease steadily with h: at level "
             f"{max(roll)} the contact holds {r['max_active']} vertices and the motion is no longer one mode (fit residual "
             f"{listing(format(roll[lev]['fit_rms'], '.2g') for lev in sorted(roll))} mm/s).")
    how = ("from its static equilibrium on the foundation (the normal force stays within "
           f"{pct(max(abs(x - 1) for x in r['normal_force_range']), 2)} of m g cos θ)" if r["start"] == "equilibrium"
           else "unstressed, just touching (the normal force then swings between "
           f"{listing(f'{x:.2f}' for x in r['normal_force_range'])} m g cos θ)")
    slips = (f"some contact vertex slips at {r['steps_slipping']} of {r['steps']} steps (at most {r['max_slipping']} "
             f"of its {r['max_active']} contact vertices at once)" if r["steps_slipping"] else
             ("its contact vertex sticks" if r["max_active"] == 1 else f"its {r['max_active']} contact vertices stick")
             + " at every step")
    return (f"Ours: the disc starts at rest {how}. Rolling (μ = {r['mu']:g}): the fitted acceleration is "
            f"{r['a']:.1f} mm/s² at level {max(roll)} against (2/3) g sin θ = {r['a_closed']:.1f} ({levels}: "
            f"{err(roll)}; the plain mean over the run {err(roll, 'mean_rel_error')}); at level {max(roll)} {slips}. "
            f"The discrete disc's moment of inertia r^T M r is {err(roll, 'inertia_error')} off m R²/2 (the P1 "
            f"velocities' lumped C), which alone puts a rigid disc's rolling {err(roll, 'discrete_inertia_rel')} off. "
            f"The centre's velocity oscillates about the rolling line by ±{r['amplitude']:.2f} mm/s with a period of "
            f"{1e3 * r['period']:.1f} ms: the disc starts without the tangential force m g sin θ / 3 of steady rolling "
            f"and swings on its tangential contact stiffness (an undamped mode of that period would swing by "
            f"±{r['amplitude_predicted']:.2f} mm/s).{trend} Sliding (μ = {sl['mu']:g}): A sticks for "
            f"{1e3 * sl['stick_until']:.2f} ms while the friction force builds up, then "
            f"{'slips at every step' if sl['all_slip_after_onset'] else 'does not slip at every step'}; the "
            f"acceleration while it slips is {sl['a']:.1f} mm/s² at level {max(slide)} against g (sin θ − μ cos θ) = "
            f"{sl['a_closed']:.1f} ({levels}: {err(slide)}), and A's slip accelerates at {sl['slip_acc']:.0f} "
            f"mm/s² against g (sin θ − 3 μ cos θ) = {sl['slip_acc_closed']:.0f} "
            f"({pct(sl['slip_acc'] / sl['slip_acc_closed'] - 1, 2)}). Tolerances: {pct(ROLL_TOL)} rolling, "
            f"{pct(SLIDE_TOL)} sliding, at every level. ", Verdict.of(roll_ok and slide_ok, roll_ok or slide_ok))


def _incline_table(meas):
    """The incline's numbers, one row per regime and level."""
    rows = []
    for reg, by in meas.items():
        for lev in sorted(by):
            m = by[lev]
            rows.append((reg, f"{m['mu']:g}", lev, f"{m['h']:g}", f"{m['dt']:g}", m["dofs"], f"{m['a']:.2f}",
                         f"{m['a_closed']:.2f}", f"{100 * m['rel_error']:+.3f} %", f"{m['a_mean']:.2f}",
                         f"{100 * m['mean_rel_error']:+.3f} %", f"{m['steps_slipping']} / {m['steps']}"))
    head = ["regime", "μ", "level", "h (mm)", "dt (s)", "dofs", "a fitted (mm/s²)", "closed form", "rel. error",
            "mean a over the run", "rel. error", "steps with a slipping vertex"]
    return html_table(head, rows)


# -------------------------------------------------------------------------------- the block
def block_measure(folder):
    """The block's deceleration and stop time, measured and closed form (rigid block)."""
    s = Series(folder)
    p, o = s.info["problem"]["parameters"], s.info["run_options"]
    m = discrete_mass(folder)
    v0, t = p["v0"], s.t
    v = s["momentum_x"] / m
    a_cf, t_cf, d_cf = block_problem.stopping(v0, p["gravity"], m, p["width"], mu=o.get("mu"),
                                              threshold=o.get("tresca_threshold"))
    sel = (v > 0.1 * v0) & (v < 0.9 * v0)
    a_fit = -float(np.polyfit(t[sel], v[sel], 1)[0])
    k = int(np.argmax(v <= 0.0)) if np.any(v <= 0.0) else None
    t_stop = math.nan if k is None else float(t[k - 1] + (t[k] - t[k - 1]) * v[k - 1] / (v[k - 1] - v[k]))
    before = t < t_cf
    closed_v = np.maximum(v0 - a_cf * t, 0.0)
    return {"law": o["friction"], "a": a_fit, "a_closed": a_cf, "t_stop": t_stop, "t_stop_closed": t_cf,
            "distance_closed": d_cf, "stop_rel_error": t_stop / t_cf - 1.0, "a_rel_error": a_fit / a_cf - 1.0,
            "max_velocity_deviation": float(np.max(np.abs(v[before] - closed_v[before]))),
            "velocity_after_stop": [float(v[t > t_cf + 1e-3].min()), float(v[t > t_cf + 1e-3].max())],
            "normal_force_range": [float(x / (m * p["gravity"])) for x in (s["contact_force"][1:].min(),
                                                                            s["contact_force"][1:].max())],
            "mass": m, "v0": v0, "wall_time": s.info.get("wall_time")}


def fig_block(fs, runs_dir, out):
    """The block's velocity against the closed form (and around the stop), its normal force and
    its friction force against their rigid-block values."""
    meas = {law: block_measure(runs_dir / r.name) for law, r in fs.block.items()}
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(17, 4.6))
    zoom = axes[0].inset_axes([0.52, 0.42, 0.45, 0.42])
    for k, (law, r) in enumerate(fs.block.items()):
        s, m = Series(runs_dir / r.name), meas[law]
        t, v, g = 1e3 * s.t, s["momentum_x"] / m["mass"], r.params["gravity"]
        lab = f"Coulomb μ = {BLOCK_MU:g}" if law == "coulomb" else f"Tresca s = {block_threshold():g} N/mm²"
        for ax in (axes[0], zoom):
            ax.plot(t, v, color=COLOURS[k], lw=2.2 - k, label=f"ours, {lab}")
        zoom.axvline(1e3 * m["t_stop"], color=COLOURS[k], lw=0.8, ls="--")
        axes[1].plot(t[1:], s["contact_force"][1:] / (m["mass"] * g), color=COLOURS[k], lw=1.2 - 0.3 * k, label=lab)
        axes[2].plot(t[1:], -s["tangential_force"][1:] / (BLOCK_MU * m["mass"] * g), color=COLOURS[k],
                     lw=1.2 - 0.3 * k, label=lab)
    m = meas["coulomb"]
    tt = np.linspace(0.0, 1e3 * fs.block["coulomb"].options["T"], 801)
    for ax in (axes[0], zoom):
        ax.plot(tt, np.maximum(m["v0"] - m["a_closed"] * tt * 1e-3, 0.0), "k:", lw=1.4,
                label=f"closed form v0 − μ g t, stop at {1e3 * m['t_stop_closed']:.2f} ms")
    t_cf = 1e3 * m["t_stop_closed"]
    zoom.set(xlim=(t_cf - 2.0, t_cf + 3.0), ylim=(-1.5, 6.5), title="around the stop (dashed: our stop times)")
    zoom.title.set_fontsize(8)
    zoom.tick_params(labelsize=7)
    zoom.grid(alpha=0.3)
    axes[0].set(xlabel="t (ms)", ylabel="velocity P$_x$ / m (mm/s)", title="the block's velocity")
    axes[1].set(xlabel="t (ms)", ylabel="Σ λ$_N$ / m g", title="normal force on the bottom (rigid block: 1)")
    axes[2].set(xlabel="t (ms)", ylabel="−Σ λ$_T$ / μ m g",
                title="friction force (rigid block: 1 while sliding, 0 at rest)", ylim=(-1.2, 1.4))
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower left")
    fig.suptitle("Friction: the elastic block (20 × 10 mm, P2/P1, midpoint, dt = 1e-4 s) sliding to a stop from "
                 "v0 = 100 mm/s")
    fig.tight_layout()
    png = save(fig, out / "friction_block.png")
    ok = all(abs(x["stop_rel_error"]) <= BLOCK_TOL for x in meas.values())
    text = "Ours: " + "; ".join(
        f"{law.capitalize()}: deceleration {x['a']:.1f} mm/s² against {x['a_closed']:.1f} "
        f"({pct(x['a_rel_error'], 2)}), the velocity within {x['max_velocity_deviation']:.2g} mm/s of the closed form "
        f"before the stop, stop at "
        f"{1e3 * x['t_stop']:.2f} ms against {1e3 * x['t_stop_closed']:.2f} ms ({pct(x['stop_rel_error'], 2)}), then "
        f"within ±{max(map(abs, x['velocity_after_stop'])):.2g} mm/s of rest; normal force "
        f"{x['normal_force_range'][0]:.3f} to {x['normal_force_range'][1]:.3f} m g"
        for law, x in meas.items()) + f". Tolerance on the stop time {pct(BLOCK_TOL)}. "
    verdict = Verdict.of(ok, all(abs(x["stop_rel_error"]) <= 3 * BLOCK_TOL for x in meas.values()))
    return Entry("friction_block", text, verdict, says=SAYS["friction_block"], png=png, numbers=meas)
