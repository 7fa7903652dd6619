"""The comparison of methods on a 2-D problem on 2 ranks against the same comparison on one (under
mpirun -n 2): every metric but the costs agrees, the reference run and its field transfer included."""
import math

from mpi4py import MPI

import pytest

from sdm_dolfinx.compare import comparison as compare
from sdm_dolfinx.post.metrics import METRICS

COMM = MPI.COMM_WORLD
pytestmark = pytest.mark.mpi


def _records(comm, out):
    cmp = compare.make_comparison("membrane", "sdm-p1bp0,standard-midpoint", [1 / 4], [0.01], T=0.3, out=out)
    return {r["method"]: r for r in compare.run_comparison(cmp, comm, say=lambda s: None)}


@pytest.mark.skipif(COMM.size == 1, reason="compares a 2-rank comparison with a serial one: needs mpirun -n 2")
def test_one_and_two_ranks_give_the_same_metrics(mpi_tmp_path):
    par = _records(COMM, mpi_tmp_path / "par")
    ser = _records(MPI.COMM_SELF, mpi_tmp_path / "ser") if COMM.rank == 0 else None
    ser = COMM.bcast(ser, root=0)
    for m, r in ser.items():
        assert r["status"] == par[m]["status"] == "finished"
        for k in METRICS:
            if k in ("wall_per_step",) or r.get(k) is None or not math.isfinite(r[k]):
                continue
            assert par[m][k] == pytest.approx(r[k], rel=1e-8, abs=1e-12), (m, k)
        assert r["u_LinfL2"] > 0 and r["penetration_max"] >= 0
