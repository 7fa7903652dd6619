"""The membrane's figures (paper section 4, Figs. 2-11): each reads its runs' time series,
draws the paper's plot and returns a report :class:`~sdm_dolfinx.study.entry.Entry` whose
verdict, computed from the numbers, says whether ours agrees with the paper.
Rank 0 only (the files are read with the serial readers)."""
import math

import numpy as np

from sdm_dolfinx import post
from sdm_dolfinx.study.series import Series, curve_diff, l2_diff
from sdm_dolfinx.paper.numbers import counting_condition, counts_ok
from sdm_dolfinx.study.entry import Entry, Verdict
from sdm_dolfinx.study.text import listing, pct
from sdm_dolfinx.study.plotting import COLOURS, plot_three, pyplot, save
from sdm_dolfinx.paper.design import BE_PAIRS, MEMBRANE_PAIRS, WELL_POSED, slug


# ------------------------------------------------------------------- Figs. 2-8: one pair
def fig_pair(study, pair, runs_dir, out, scheme="midpoint"):
    """Figs. 2-8: one pair, several dt: plot and verdict."""
    group = study.pairs if scheme == "midpoint" else study.be
    num = MEMBRANE_PAIRS[pair] if scheme == "midpoint" else BE_PAIRS[pair]
    key = f"fig{num:02d}"
    dts = sorted(group[pair], reverse=True)
    ser = [Series(runs_dir / group[pair][dt].name) for dt in dts]
    png = plot_three(ser, [f"dt = {dt:g}" for dt in dts],
                     f"Fig. {num}: {pair}, {'midpoint' if scheme == 'midpoint' else 'backward Euler'}, h = 0.1",
                     out / f"{key}_{slug(pair)}_{'mp' if scheme == 'midpoint' else 'be'}.png")
    nums = {"dt": dts, "energy_dev": [s.energy_dev() for s in ser], "growth": [s.growth() for s in ser],
            "final_error": [s.final_error() for s in ser], "stress_peak": [float(s["lambda_probe"].max()) for s in ser],
            "stress_oscillation": [s.oscillation() for s in ser], "failed": [s.failed for s in ser]}
    nums["u_change"] = [curve_diff(ser[k + 1], ser[k], "u_probe", 0.02) for k in range(len(ser) - 1)]
    nums["rebound"] = [s.rebound() for s in ser]
    dstr = [f"{dt:g}" for dt in dts]
    if scheme != "midpoint":
        text, verdict = _backward_euler_text(study, pair, ser, nums, dstr)
    elif WELL_POSED[pair]:
        text, verdict = _stable_text(nums, dstr)
    else:
        good = [Series(runs_dir / group["P1+/P0"][dt].name) for dt in dts] if "P1+/P0" in group else None
        text, verdict = _unstable_text(ser, nums, dstr, good)
    return Entry(key, text, verdict, png=png, numbers=nums)


def _stable_text(nums, dstr):
    """A well-posed pair with the midpoint scheme: energy conserved as dt decreases, and converging.
    Returns (sentence, verdict)."""
    dev, du = nums["energy_dev"], nums["u_change"]
    decreasing = all(dev[k + 1] < dev[k] for k in range(len(dev) - 1))
    if len(du) >= 2:
        converging = du[-1] < du[0] and du[-1] < 0.01      # the paper: the finest two are indistinguishable
        conv_text = (f"; the centre displacement changes by {listing(pct(x) for x in du)} of its initial height "
                     f"0.02 from one dt to the next ({'converging' if du[-1] < du[0] else 'not converging'}; between "
                     f"dt = {dstr[-2]} and {dstr[-1]}: {'not visible' if du[-1] < 0.01 else 'visible'} at plot "
                     f"scale)")
    else:
        converging = True
        conv_text = (f"; the centre displacement changes by {pct(du[0])} of its initial height 0.02 between the "
                     f"two time steps (convergence needs a third dt: the full study adds 1e-4)")
    return (f"Ours: the largest energy deviation max|J−J0|/J0 is {listing(pct(x) for x in dev)} for dt = "
            f"{listing(dstr)}, {'decreasing' if decreasing else 'not decreasing'} with dt" + conv_text
            + f"; peak contact stress at the centre {listing(f'{x:.3g}' for x in nums['stress_peak'])}. ",
            Verdict.of(decreasing and converging and dev[-1] < 0.05, decreasing or du[-1] < du[0]))


def _unstable_text(ser, nums, dstr, good):
    """An ill-posed pair with the midpoint scheme: the energy grows after the impact, more for small dt.
    Returns (sentence, verdict)."""
    g = nums["growth"]
    worse = _worst_at_smallest_dt(g)
    ref = [x.rebound() for x in good] if good else None
    ref_peak = listing(f"{x['lambda_probe'].max():.3g}" for x in good) if good else ""
    return (f"Ours: the energy reaches {listing('∞ (blew up)' if math.isinf(x) else f'{x:.3g} J0' for x in g)} "
            f"for dt = {listing(dstr)} (first contact at t = {ser[-1].first_contact():.3g}); after the impact the "
            f"centre rises to {listing(f'{x:.3g}' for x in nums['rebound'])} times its initial height"
            + (f" (P1+/P0: {listing(f'{x:.3g}' for x in ref)})" if ref else "")
            + f" and the peak contact stress is {listing(f'{x:.3g}' for x in nums['stress_peak'])}"
            + (f" (P1+/P0: {ref_peak})" if ref else "") + ". "
            + ("The growth is largest for the smallest time step" if worse else
               "The growth is not largest for the smallest time step")
            + ("" if all(g[k + 1] >= g[k] for k in range(len(g) - 1)) else " (not monotone over the larger ones)")
            + ". ", unstable_verdict(g))


def unstable_verdict(growth):
    """The paper's claim for an ill-posed pair (Figs. 3 and 4): the energy grows very fast after the
    impact (here: to more than 1.5 J0 at the smallest dt), and "the instabilities are more important
    for the smallest time step" (the smallest dt's growth is the largest). The larger time steps
    are not ranked among themselves: the paper says nothing of them, and an ill-posed run's growth
    at a given dt is round-off amplified (12.78 or 13.30 J0 at dt = 1e-3 on two machines)."""
    grows = growth[-1] > 1.5
    return Verdict.of(grows and _worst_at_smallest_dt(growth), grows)


def _worst_at_smallest_dt(growth):
    """The smallest time step's (the last) growth is the largest."""
    return growth[-1] >= max(growth)


def _backward_euler_text(study, pair, ser, nums, dstr):
    """Backward Euler: the energy never increases; its loss at impact vanishes with dt only
    for a well-posed pair. Adds the losses to ``nums``; returns (sentence, verdict)."""
    loss = [(-x if not math.isnan(x) else x) for x in nums["final_error"]]
    lc = [s.losses()[0] for s in ser]
    lf = [s.losses()[1] for s in ser]
    mono = max(s.max_increase() for s in ser)
    nums.update(loss=loss, contact_loss=lc, flight_loss=lf, max_step_increase=mono)
    base = (f"Ours: the energy never increases (largest one-step rise {mono:.1e} J0); it loses "
            f"{listing(pct(x) for x in loss)} of J0 by t = {study.membrane_T:g} for dt = {listing(dstr)}, of which "
            f"{listing(pct(x) for x in lc)} during the steps in contact. ")
    if WELL_POSED[pair]:
        ok = all(loss[k + 1] < loss[k] for k in range(len(loss) - 1)) and lc[-1] < 0.5 * lc[0]
        return base + ("The loss, at impact included, shrinks as dt decreases. " if ok else
                       "The loss does not shrink as dt decreases. "), Verdict.of(ok and mono < 1e-8)
    ok = lc[-1] > 0.05 and lc[-1] > 0.5 * lc[0]
    return base + ("The loss at impact stays as dt decreases. " if ok else
                   "The loss at impact shrinks with dt. "), Verdict.of(ok and mono < 1e-8, ok)


# ----------------------------------------------------------------- Figs. 9-11: meshes
def fig09(study, runs_dir, out):
    """Fig. 9: P1/P0, backward Euler, several meshes: the loss at impact does not vanish."""
    plt = pyplot()
    Ns = sorted(study.fig9)
    ser = [Series(runs_dir / study.fig9[N].name) for N in Ns]
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for k, (N, s) in enumerate(zip(Ns, ser)):
        ax.plot(s.t, s["energy"], color=COLOURS[k], label=f"h = 1/{N}")
    ax.set_xlabel("t")
    ax.set_ylabel("energy $J^h$")
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title("Fig. 9: P1/P0, backward Euler, dt = 1e-3")
    fig.tight_layout()
    png = save(fig, out / "fig09_P1-P0_be_meshes.png")
    lc = [s.losses()[0] for s in ser]
    lf = [s.losses()[1] for s in ser]
    ok = min(lc) > 0.05 and lc[-1] > 0.5 * lc[0]
    text = (f"Ours: during the steps in contact the energy drops by {listing(pct(x) for x in lc)} of J0 for h = "
            f"{listing(f'1/{N}' for N in Ns)} (in free flight by {listing(pct(x) for x in lf)}): the loss at impact "
            f"{'does not vanish' if ok else 'shrinks'} as h decreases. ")
    return Entry("fig09", text, Verdict.of(ok), png=png, numbers={"N": Ns, "contact_loss": lc, "flight_loss": lf})


def _exclusion_text(pairs, Ns, series_of):
    """A sentence on the meshes where a pair fails the counting condition of (7) (left out)."""
    parts = []
    for p in pairs:
        for N in Ns:
            if not counts_ok(p, N):
                h, room = counting_condition(p, N)
                g = series_of(p, N).growth()
                parts.append(f"on h = 1/{N} {p} fails the counting condition of (7), dim H = {h} > dim W − N_g = "
                             f"{room}, and its energy reaches {'∞' if math.isinf(g) else f'{g:.3g} J0'}")
    if not parts:
        return ""
    return "; ".join(parts) + " (left out of the comparison below); "


def fig10(study, runs_dir, out):
    """Fig. 10: h and dt decreasing together (dt/h fixed): the two pairs get closer."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6), sharey=True)
    shift = 0.03
    ser = {}
    for ax, pair in zip(axes, study.fig10):
        Ns = sorted(study.fig10[pair])
        ser[pair] = {N: Series(runs_dir / study.fig10[pair][N].name) for N in Ns}
        for k, N in enumerate(Ns):
            s = ser[pair][N]
            ax.plot(s.t, s["u_probe"] + shift * k, color=COLOURS[k],
                    label=f"h = 1/{N}, dt = {study.fig10[pair][N].options['dt']:.4g} (+{shift * k:g})"
                    + ("" if counts_ok(pair, N) else ": dim H > dim W − N_g"))
        ax.set_title(f"{pair}, midpoint, dt/h = 5e-3")
        ax.set_xlabel("t")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("displacement at (0.5, 0.5), shifted")
    fig.suptitle("Fig. 10: h and dt decreasing together")
    fig.tight_layout()
    png = save(fig, out / "fig10_h_dt_together.png")
    pairs = list(ser)
    allN = sorted(set.intersection(*[set(ser[p]) for p in pairs]))
    Ns = [N for N in allN if all(counts_ok(p, N) for p in pairs)]
    excluded = _exclusion_text(pairs, allN, lambda p, N: ser[p][N])
    between = [l2_diff(ser[pairs[0]][N], ser[pairs[1]][N], "u_probe") for N in Ns]
    succ = {p: [l2_diff(ser[p][Ns[k + 1]], ser[p][Ns[k]], "u_probe") for k in range(len(Ns) - 1)] for p in pairs}
    ok = len(between) >= 2 and between[-1] < between[0]
    slow = {p: len(v) >= 2 and v[-1] > 0.5 * v[0] for p, v in succ.items()}
    text = ("Ours: " + excluded
            + f"the {pairs[0]} and {pairs[1]} centre displacements differ by {listing(pct(x) for x in between)} "
            f"(relative L²(0, T) difference) for h = {listing(f'1/{N}' for N in Ns)}: the two methods "
            f"{'get closer' if ok else 'do not get closer'} as h and dt decrease. From one mesh to the next the "
            + "; ".join(f"{p} curve changes by {listing(pct(x) for x in succ[p])}" for p in pairs)
            + (" (slow convergence, as the paper remarks). " if all(slow.values()) and Ns else ". "))
    return Entry("fig10", text, Verdict.of(ok), png=png,
                 numbers={"N": Ns, "pair_difference": between, "successive_change": succ})


def fig11(study, runs_dir, out):
    """Fig. 11: the energy error at T against dt/h, one curve per mesh, for two pairs."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6), sharey=True)
    nums, verdicts, texts, signs = {}, [], [], set()
    for ax, pair in zip(axes, study.fig11):
        nums[pair], ok, text = _fig11_pair(study, pair, runs_dir, ax, signs)
        verdicts.append(ok)
        texts.append(text)
    axes[0].set_ylabel("|J(T) − J0| / J0 (%)")
    fig.suptitle("Fig. 11: relative energy error at the final time against dt/h")
    fig.tight_layout()
    png = save(fig, out / "fig11_energy_error_vs_dt_over_h.png")
    text = ("Ours: " + "; ".join(texts) + ". "
            + ("J(T) − J0 takes both signs, so single points of |J(T) − J0| dip. "
               if len(signs - {0.0}) > 1 else ""))
    verdict = Verdict.of(all(v[0] for v in verdicts), all(v[0] or v[1] for v in verdicts))
    return Entry("fig11", text, verdict, png=png, numbers=nums)


def _fig11_pair(study, pair, runs_dir, ax, signs):
    """One panel of Fig. 11: (numbers, (agrees, agrees in part), sentence); adds the signs of
    J(T) - J0 to ``signs``."""
    Ns = sorted(study.fig11[pair])
    err = {}
    for k, N in enumerate(Ns):
        ratios = sorted(study.fig11[pair][N])
        signed = [Series(runs_dir / study.fig11[pair][N][r].name).final_error() for r in ratios]
        signs.update(np.sign(signed).tolist())
        e = [abs(x) for x in signed]
        err[N] = dict(zip(ratios, e))
        ax.loglog(ratios, [100 * x for x in e], "o-", color=COLOURS[k], label=f"h = 1/{N}")
    ax.set_title(f"{pair}, midpoint, T = {study.membrane_T:g}")
    ax.set_xlabel("dt / h")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    excluded = _exclusion_text([pair], Ns, lambda p, N: Series(runs_dir / study.fig11[p][N][min(
        study.fig11[p][N])].name))
    Ns = [N for N in Ns if counts_ok(pair, N)]
    ratios = sorted(err[Ns[0]])
    slopes = {N: post.convergence_rate(ratios, [max(err[N][r], 1e-16) for r in ratios]) for N in Ns}
    growth = [err[Ns[-1]][r] / err[Ns[0]][r] for r in ratios]
    gm = float(np.exp(np.mean(np.log(growth))))          # typical finest/coarsest ratio at equal dt/h
    largest = max(err[Ns[-1]].values())
    falls = all(v > 0 for v in slopes.values())
    nums = {"errors": {str(N): {str(r): v for r, v in err[N].items()} for N in err},
            "slope_vs_dt_over_h": {str(N): v for N, v in slopes.items()},
            "finest_over_coarsest_at_same_ratio": growth, "geometric_mean_ratio": gm}
    text = (f"{pair}: {excluded}the error {'falls' if falls else 'does not always fall'} with dt "
            f"(fitted log-log slopes {listing(f'{slopes[N]:.2g}' for N in Ns)} for h = "
            f"{listing(f'1/{N}' for N in Ns)}); at equal dt/h the error on h = 1/{Ns[-1]} is "
            f"{listing(f'{x:.2g}' for x in growth)} times that on h = 1/{Ns[0]} (geometric mean {gm:.2g}: "
            + ("no systematic growth" if gm <= 3 else "it grows with refinement")
            + f"), its largest error being {pct(largest)}")
    return nums, (falls and gm <= 3.0, falls and largest < 0.01), text
