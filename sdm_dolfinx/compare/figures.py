"""The comparison's figures, in the style of Doyen, Ern, Piperno (2011): per method, the displacement,
velocity and contact stress at the contact point against the exact (or reference) curve and the
energy against time; the convergence of each metric with its fitted rate.
"""
import math

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import io as sdm_io
from sdm_dolfinx.compare.table import RATE_METRICS, finest, rates
from sdm_dolfinx.study.plotting import COLOURS, pyplot, save
from sdm_dolfinx.post.metrics import velocity_of

#: the metrics of the convergence figure (one panel each)
CONVERGENCE = RATE_METRICS + ("penetration_max", "oscillation_index")
#: at most this many methods per contact-point figure (one row each)
ROWS_PER_FIGURE = 9


def _series(folder):
    try:
        return sdm_io.read_timeseries(folder, MPI.COMM_SELF)
    except Exception:              # a run refused before it wrote anything
        return None


def _truth_curves(truth, t):
    """(u, v, s) of the exact or reference solution at the times ``t``."""
    u = truth["u"](t)
    return u, velocity_of(t, u), truth["s"](t)


def contact_point_figures(cmp, records, truth, out):
    """One row per method at the finest (h, dt): u, v and contact stress at the contact point and the
    energy E/E(0) against t, the exact (or reference) curve in black. Returns the PNG names."""
    h, dt = finest(records)
    rows = [r for r in records if r["h"] == h and r["dt"] == dt and r.get("status") in ("finished", "failed")]
    names = []
    for k in range(0, len(rows), ROWS_PER_FIGURE):
        chunk = rows[k:k + ROWS_PER_FIGURE]
        name = f"compare_contact_{k // ROWS_PER_FIGURE + 1}.png"
        _contact_figure(cmp, chunk, truth, out / name, h, dt)
        names.append(name)
    return names


def _contact_figure(cmp, rows, truth, path, h, dt):
    plt = pyplot()
    fig, axes = plt.subplots(len(rows), 4, figsize=(16, 1.9 * len(rows) + 0.8), squeeze=False, sharex=True)
    for i, r in enumerate(rows):
        ts = _series(cmp.folder(r["method"], h, dt))
        ax = axes[i]
        if ts is None:
            continue
        t = np.asarray(ts["t"])
        if truth is not None:
            tt = np.linspace(0.0, t[-1], 2000)
            for a, y in zip(ax[:3], _truth_curves(truth, tt)):
                a.plot(tt, y, color="k", lw=1.0)
        c = COLOURS[0] if r.get("status") == "finished" else COLOURS[3]
        ax[0].plot(t, ts["u_probe"], color=c, lw=0.9)
        ax[1].plot(t, velocity_of(t, ts["u_probe"]), color=c, lw=0.9)
        ax[2].plot(t, ts["lambda_probe"], color=c, lw=0.9)
        E = np.asarray(ts["energy"])
        ax[3].plot(t, E / E[0] if E[0] else E, color=c, lw=0.9)
        ax[0].set_ylabel(r["method"] + (" (failed)" if r.get("status") == "failed" else ""), fontsize=8)
        if truth is not None:
            tt = np.linspace(0.0, t[-1], 500)
            for a, y in zip(ax[1:3], _truth_curves(truth, tt)[1:]):
                _clip(a, y)
    for a, title in zip(axes[0], ("displacement at the contact point", "velocity (difference quotient)",
                                  "contact stress", "energy E / E(0)")):
        a.set_title(title, fontsize=9)
    for a in axes[-1]:
        a.set_xlabel("t")
    for a in axes.flat:
        a.grid(alpha=0.3)
        a.tick_params(labelsize=7)
    fig.suptitle(f"{cmp.problem}: h = {h:g}, dt = {dt:g} (black: "
                 f"{'exact' if cmp.exact is not None else 'reference'})", fontsize=10)
    fig.tight_layout()
    save(fig, path)


def _clip(ax, exact):
    """The axis within 3x the exact curve's range: a spike of a standard mass does not flatten the rest."""
    top = float(np.max(np.abs(exact)))
    if top > 0:
        lo, hi = ax.get_ylim()
        ax.set_ylim(max(lo, -2 * top), min(hi, 3 * top))


def energy_figure(cmp, records, out):
    """E(t)/E(0) of every method at the finest (h, dt) in one panel."""
    h, dt = finest(records)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(10, 5))
    styles = ["-", "--", ":", "-."]
    k = 0
    for r in records:
        if r["h"] != h or r["dt"] != dt or r.get("status") not in ("finished", "failed"):
            continue
        ts = _series(cmp.folder(r["method"], h, dt))
        if ts is None:
            continue
        E = np.asarray(ts["energy"])
        ax.plot(ts["t"], E / E[0] if E[0] else E, color=COLOURS[k % len(COLOURS)],
                ls=styles[(k // len(COLOURS)) % len(styles)], lw=1.0, label=r["method"])
        k += 1
    ax.set_xlabel("t")
    ax.set_ylabel("E / E(0)")
    lo, hi = ax.get_ylim()
    ax.set_ylim(max(lo, 0.0), min(hi, 2.0))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title(f"{cmp.problem}: energy (contact energy included), h = {h:g}, dt = {dt:g}")
    fig.tight_layout()
    return save(fig, out / "compare_energy.png")


def convergence_figure(cmp, rates, out):
    """One panel per metric of :data:`CONVERGENCE`: each method's values along its fitted refinement
    path (log-log against h or dt), its rate in the legend."""
    plt = pyplot()
    n = len(CONVERGENCE)
    cols = 4
    fig, axes = plt.subplots(math.ceil(n / cols), cols, figsize=(18, 4.2 * math.ceil(n / cols)), squeeze=False)
    styles = ["-o", "--s", ":^", "-.v"]
    for a, metric in zip(axes.flat, CONVERGENCE):
        for k, (method, per) in enumerate(rates.items()):
            fit = per.get(metric)
            if not fit:
                continue
            a.loglog(fit["sizes"], fit["values"], styles[(k // len(COLOURS)) % len(styles)],
                     color=COLOURS[k % len(COLOURS)], ms=3, lw=1.0, label=f"{method} ({fit['rate']:.2f})")
        a.set_title(metric, fontsize=9)
        a.set_xlabel("h (or dt)")
        a.grid(alpha=0.3, which="both")
        if a.lines:
            a.legend(fontsize=6)
    for a in list(axes.flat)[n:]:
        a.axis("off")
    fig.suptitle(f"{cmp.problem}: convergence (legend: fitted rate)")
    fig.tight_layout()
    return save(fig, out / "compare_convergence.png")


def all_figures(cmp, records, truth, out):
    """Every figure of the comparison (``truth``: the exact or reference values at the contact
    point, :func:`~sdm_dolfinx.post.metrics.exact_truth`); returns {name: [PNG names]}."""
    fitted = rates(records, CONVERGENCE)
    return {"contact_point": contact_point_figures(cmp, records, truth, out),
            "energy": [energy_figure(cmp, records, out)],
            "convergence": [convergence_figure(cmp, fitted, out)]}
