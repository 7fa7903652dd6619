"""A run's time series as the studies read it (:class:`Series`: energy deviation, losses, first
contact, rebound, oscillation), and two series compared in time (max, L2 and L1 differences)."""
import math
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx import io as sdm_io
from sdm_dolfinx.study.runs import read_run_info


# ----------------------------------------------------------------------- one run's series
class Series:
    """A run's time series and status, read on the calling rank."""

    def __init__(self, folder):
        self.folder = Path(folder)
        self.info = read_run_info(self.folder) or {}
        self.ts = sdm_io.read_timeseries(self.folder, MPI.COMM_SELF)
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


