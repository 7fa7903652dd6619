"""``--vi-solver``: PETSc's vinewtonssls gives the default semi-smooth Newton's time series on
the membrane through the first impact (P1+/P0 and P2/P1), to its tolerance.

Both stop at a complementarity residual of -sdm_vi_rtol (1e-10) x max|b|, but the semi-smooth
Newton's active-set solution is exact to round-off while vinewtonssls' Fischer-Burmeister
iterates stop within the tolerance: the two drift apart by ~1e-12 of the scale per step,
3e-7 (P1+/P0) and 1e-7 (P2/P1) of each column's largest value after 300 steps, measured; we
allow 1e-6. The active sets are the same at every step.
"""
import csv

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli

COMM = MPI.COMM_WORLD
#: agreement of the time series, relative to each column's largest value
RTOL = 1e-6


def _series(folder):
    text = COMM.bcast((folder / "timeseries.csv").read_text() if COMM.rank == 0 else None, root=0)
    rows = list(csv.DictReader(text.splitlines()))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


@pytest.mark.parametrize("pair", ["P1+/P0", "P2/P1"])
def test_vinewtonssls_gives_the_semismooth_newton_time_series(pair, mpi_tmp_path):
    base = ["membrane", "--N", "8", "--pair", pair, "--dt", "1e-3", "--T", "0.3", "--quiet"]
    series = {}
    for solver in ("ssn", "vinewtonssls"):
        out = mpi_tmp_path / solver
        assert cli.main(base + ["--vi-solver", solver, "--out", str(out)]) == 0
        COMM.Barrier()
        series[solver] = _series(out)
    a, b = series["vinewtonssls"], series["ssn"]
    assert len(a["step"]) == len(b["step"]) == 301
    assert b["n_active"].max() >= 10 and np.argmax(b["n_active"] > 0) < 260       # through the first impact
    np.testing.assert_array_equal(a["n_active"], b["n_active"])
    for c in ("energy", "kinetic", "potential", "u_probe", "lambda_probe"):
        np.testing.assert_allclose(a[c], b[c], rtol=0, atol=RTOL * np.max(np.abs(b[c])), err_msg=c)
