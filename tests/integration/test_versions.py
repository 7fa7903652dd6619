"""The same membrane run on two dolfinx versions gives the same time series.

``make test-dolfinx09`` and ``make test-dolfinx011`` run the paper's Fig. 2 case (P1+/P0, midpoint,
N = 10, dt = 1e-3, T = 0.8) inside the Debian 13 chroot (dolfinx 0.9, or 0.11 from PyPI's wheel with
MUMPS instead of CHOLMOD and MPICH) and on the host (dolfinx 0.5.2), on 1
and on 2 ranks, into ``SDM_VERSION_RUNS/{host,other}-np{1,2}``, and then runs this test on
the host. Both versions assemble the same forms with the same quadrature and solve the
same LCP with direct factorisations, so the series may differ only by round-off amplified
through 800 steps: we ask 1e-9 relative to each column's largest magnitude. Measured against
0.5.2: 0.9 ~1e-11 in every column; 0.11 (another BLAS, MUMPS instead of CHOLMOD, numpy 2) ~3e-11
in the energies and 1.5e-10 in the centre's displacement, a difference of 7e-16 at step 1 that
grows through the impacts to step 800 as round-off does (1 against 2 ranks of one version
differ by 1e-11 to 4e-11; CHOLMOD against MUMPS on 0.5.2 by 5e-12), with the same active set at
every step (below: at 99 % of them at least). 1e-9 is 6.7x the largest drift measured: a version difference
beyond round-off (an element, an assembly, a solver) is what it guards against. Without SDM_VERSION_RUNS (a plain ``make test``) there is nothing to compare
with and the test is skipped; SDM_REQUIRE_VERSIONS=1 makes that a failure.
"""
import csv
import json
import os
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

RUNS = os.environ.get("SDM_VERSION_RUNS")
RTOL = 1e-9
COLUMNS = ("energy", "kinetic", "potential", "u_probe", "lambda_probe")

if not RUNS and os.environ.get("SDM_REQUIRE_VERSIONS") == "1":
    raise RuntimeError("SDM_REQUIRE_VERSIONS=1 but SDM_VERSION_RUNS is not set")
pytestmark = [
    pytest.mark.skipif(not RUNS, reason="needs the runs of two dolfinx versions (make test-dolfinx09, test-dolfinx011)"),
    pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="compares files: serial only"),
]


def _load(folder):
    info = json.loads((folder / "run.json").read_text())
    with open(folder / "timeseries.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    series = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    return info, series


def _pairs():
    root = Path(RUNS or ".")
    return sorted(p.name.split("-", 1)[1] for p in root.glob("host-np*"))


@pytest.mark.parametrize("ranks", _pairs() if RUNS else ["np1"])
def test_membrane_series_agree_between_versions(ranks):
    root = Path(RUNS)
    assert _pairs(), f"no host-np* runs in {root}"
    host, other = root / f"host-{ranks}", root / f"other-{ranks}"
    assert other.is_dir(), f"{other} is missing: the chroot run did not happen"
    hi, hs = _load(host)
    oi, os_ = _load(other)
    # two different versions, the same finished run on the same number of ranks
    assert hi["versions"]["dolfinx"] != oi["versions"]["dolfinx"], "both runs used one dolfinx version"
    assert hi["status"] == oi["status"] == "finished"
    assert hi["ranks"] == oi["ranks"] == int(ranks[2:])
    for key in ("pair", "mass", "scheme", "dt", "T", "steps", "dim_W", "dim_H", "N_g"):
        assert hi[key] == oi[key], key
    np.testing.assert_array_equal(hs["step"], os_["step"])
    assert len(hs["step"]) == hi["steps"] + 1
    # the run is not trivial: contact happened (the paper's first impact is at t ~ 0.26)
    assert hs["n_active"].max() > 0 and hs["lambda_probe"].max() > 0
    for c in COLUMNS:
        scale = np.max(np.abs(hs[c]))
        diff = np.max(np.abs(hs[c] - os_[c]))
        assert diff <= RTOL * scale, (
            f"{c}: dolfinx {hi['versions']['dolfinx']} and {oi['versions']['dolfinx']} differ by "
            f"{diff:.3e} = {diff / scale:.2e} x max |{c}| (allowed {RTOL:g})")
    # the active sets are the same at every step but those where a vertex sits on the obstacle
    # to round-off (a multiplier or gap of ~1e-15 decides in or out): measured identical at all
    assert np.mean(hs["n_active"] == os_["n_active"]) >= 0.99
