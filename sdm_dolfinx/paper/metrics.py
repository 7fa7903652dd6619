"""The numbers behind the verdicts: a run's time series and what is measured on it, the
counting condition of (7), the rates of the disc's H¹ convergence (Fig. 16; the errors of
Table 2 are :mod:`.table2`'s) and the energy recomputed from the stored fields; with the few
helpers that put numbers into sentences.
"""
import html
import math
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat, post
from sdm_dolfinx.paper.runs import read_run_info
from sdm_dolfinx.paper.study import MEMBRANE_PAIRS, PAPER_TABLE2

COMM = MPI.COMM_WORLD


# ----------------------------------------------------------------------- one run's series
class Series:
    """A run's time series and status, read on the calling rank."""

    def __init__(self, folder):
        self.folder = Path(folder)
        self.info = read_run_info(self.folder) or {}
        self.ts = post.read_timeseries(self.folder, MPI.COMM_SELF)
        self.failed = self.info.get("status") == "failed"
        self.error = self.info.get("error", "")

    def __getitem__(self, k):
        return self.ts[k]

    @property
    def t(self):
        return self.ts["t"]

    @property
    def E0(self):
        return self.ts["energy"][0]

    def energy_dev(self):
        """max_t |J - J0| / |J0| (inf if the run blew up)."""
        if self.failed:
            return math.inf
        E = self.ts["energy"]
        return float(np.max(np.abs(E - self.E0)) / abs(self.E0))

    def growth(self):
        """max_t J / J0 (inf if the run blew up)."""
        return math.inf if self.failed else float(np.max(self.ts["energy"]) / self.E0)

    def final_error(self):
        """(J(T) - J0) / J0."""
        return math.nan if self.failed else float((self.ts["energy"][-1] - self.E0) / self.E0)

    def losses(self):
        """Energy lost (relative to J0) during the steps in contact and during free flight."""
        E, act = self.ts["energy"], self.ts["n_active"]
        dE = E[:-1] - E[1:]
        contact = act[1:] > 0
        return float(dE[contact].sum() / self.E0), float(dE[~contact].sum() / self.E0)

    def first_contact(self):
        hit = np.flatnonzero(self.ts["n_active"] > 0)
        return float(self.t[hit[0]]) if len(hit) else math.nan

    def max_increase(self):
        """Largest energy increase of one step, relative to J0 (backward Euler: <= round-off)."""
        E = self.ts["energy"]
        return float(np.max(E[1:] - E[:-1], initial=0.0) / abs(self.E0))

    def rebound(self):
        """Highest centre displacement after the first contact, over the initial one."""
        hit = np.flatnonzero(self.ts["n_active"] > 0)
        u = self.ts["u_probe"]
        return float(np.max(u[hit[0]:]) / u[0]) if len(hit) and u[0] != 0 else math.nan

    def oscillation(self, col="lambda_probe"):
        """Total variation of a column over twice its peak: ~1 per smooth bump, large if it oscillates."""
        y = self.ts[col]
        peak = np.max(np.abs(y))
        return float(np.sum(np.abs(np.diff(y))) / (2 * peak)) if peak > 0 else 0.0


# ------------------------------------------------------------------ comparing two series
def curve_diff(a, b, col, scale):
    """max over a's times (within both) of |a - b| / scale, b interpolated in time."""
    t = a.t[a.t <= b.t[-1] + 1e-12]
    if not len(t):
        return math.nan
    return float(np.max(np.abs(a[col][:len(t)] - np.interp(t, b.t, b[col]))) / scale)


def l2_diff(a, b, col):
    """(∫|a − b|² dt / ∫|b|² dt)^½ on a's time grid (b interpolated)."""
    t = a.t[a.t <= b.t[-1] + 1e-12]
    bb = np.interp(t, b.t, b[col])
    den = compat.trapezoid(bb ** 2, t)
    return float(np.sqrt(compat.trapezoid((a[col][:len(t)] - bb) ** 2, t) / den)) if den > 0 else math.nan


def l1_diff(a, b, col):
    """∫|a − b| dt / ∫|b| dt on a's time grid."""
    t = a.t[a.t <= b.t[-1] + 1e-12]
    bb = np.interp(t, b.t, b[col])
    den = compat.trapezoid(np.abs(bb), t)
    return float(compat.trapezoid(np.abs(a[col][:len(t)] - bb), t) / den) if den > 0 else math.nan


# ------------------------------------------------------------------- condition (7) counts
def counting_condition(pair, N):
    """(dim H^h, dim W^h_0 - N_g) for the membrane on N x N squares; condition (7) needs
    dim H^h <= dim W^h - N_g (section 2), W^h without the Dirichlet dofs and H^h with all its dofs."""
    ng = (N - 1) ** 2
    w = {"P1": (N - 1) ** 2, "P1+": (N - 1) ** 2 + 2 * N * N, "P2": (2 * N - 1) ** 2}[pair.split("/")[0]]
    h = {"P0": 2 * N * N, "P1": (N + 1) ** 2, "P2": (2 * N + 1) ** 2}[pair.split("/")[1]]
    if pair.split("/")[0] == pair.split("/")[1]:
        h = w                                       # standard Galerkin: H^h = W^h
    return h, w - ng


def counts_ok(pair, N):
    h, room = counting_condition(pair, N)
    return h <= room


# ------------------------------------------------------- the disc's convergence rates
def fit_rates(levels, ref_level, errors, semi, dofs):
    """Convergence rates of the H1 errors against the nominal h of Table 2 (h halves per level).

    ``rate`` fits the levels the way the paper did: it left out the level next to its
    reference (h = 0.14 mm, "too close to the reference"), when at least two remain.
    """
    coarse = [lev for lev in levels if lev != ref_level]
    h = {lev: PAPER_TABLE2[lev][1] if lev in PAPER_TABLE2 else 2.0 / 2 ** (lev - 1) for lev in levels}
    fit = [lev for lev in coarse if lev != ref_level - 1] if len(coarse) >= 3 else coarse
    rate = post.convergence_rate([h[x] for x in fit], [errors[x] for x in fit])
    return {"h_nominal": h, "fit_levels": fit, "rate": rate,
            "rate_all_levels": post.convergence_rate([h[x] for x in coarse], [errors[x] for x in coarse]),
            "rate_from_dofs": -2 * post.convergence_rate([dofs[x] for x in coarse], [errors[x] for x in coarse]),
            "rate_seminorm": post.convergence_rate([h[x] for x in fit], [semi[x] for x in fit])}


# ------------------------------------------------------------------------ energy checks
def energy_checks(study, runs_dir, comm=COMM):
    """The energy recomputed from state.h5 against timeseries.csv, for a few runs (collective)."""
    runs = [study.pairs[p][1e-3] for p in MEMBRANE_PAIRS] + [study.disc["P2/P1"][1e-4]]
    out = []
    for r in runs:
        res = post.recompute_energy(runs_dir / r.name, comm)
        out.append({"run": r.name, "states": int(len(res["step"])), "max_rel_diff": res["max_rel_diff"],
                    "max_roundoff_ratio": res["max_roundoff_ratio"], "stored_dtype": res["stored_dtype"]})
    return out


# ------------------------------------------------------------------- numbers in words
def pct(x, digits=2):
    """A ratio as a percentage (n/a, or ∞ for a run that blew up)."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "n/a"
    if math.isinf(x):
        return "∞ (blew up)"
    return f"{100 * x:.{digits}g} %" if abs(100 * x) < 10 ** digits else f"{100 * x:.0f} %"


def listing(xs):
    return ", ".join(xs)


def html_table(header, rows, markup_header=False):
    """An HTML table, every cell escaped; ``markup_header``: the header cells are HTML already
    (``e<sub>y</sub>``)."""
    h = "".join(f"<th>{c if markup_header else html.escape(str(c))}</th>" for c in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def verdict(ok, partly=False):
    """The sentence the report's summary reads (agrees, in part, does not agree)."""
    return "Ours agrees." if ok else ("Ours agrees in part." if partly else "Ours does not agree.")


def jsonable(d):
    """``d`` with string keys and Python numbers (for numbers.json)."""
    if isinstance(d, dict):
        return {str(k): jsonable(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [jsonable(v) for v in d]
    if isinstance(d, (np.floating, np.integer)):
        return d.item()
    return d
