"""The membrane on 2 ranks against the same run on one (under mpirun -n 2)."""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import membrane, simulate

COMM = MPI.COMM_WORLD
pytestmark = pytest.mark.mpi


@pytest.mark.skipif(COMM.size == 1, reason="compares a 2-rank run with a serial one: needs mpirun -n 2")
@pytest.mark.parametrize("pair,mass", [("P1+/P0", None), ("P2/P1", "lumped"), ("P2/P1", "consistent")])
def test_one_and_two_ranks_agree(pair, mass):
    """The distributed run equals a serial run of the same problem to ~1e-10 relative."""
    kw = dict(pair=pair, mass=mass, dt=2e-3, T=0.6)
    par = simulate(membrane.problem(N=10, comm=COMM), **kw).timeseries
    ser = simulate(membrane.problem(N=10, comm=MPI.COMM_SELF), **kw).timeseries if COMM.rank == 0 else None
    ser = COMM.bcast(ser, root=0)
    for c in ("energy", "kinetic", "potential", "u_probe", "lambda_probe", "n_active"):
        scale = max(np.abs(ser[c]).max(), 1e-300)
        assert np.max(np.abs(par[c] - ser[c])) <= 1e-10 * scale, c

