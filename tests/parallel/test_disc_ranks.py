"""The disc on 2 ranks against the same run on one (under mpirun -n 2)."""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import disc, simulate

COMM = MPI.COMM_WORLD
pytestmark = pytest.mark.mpi


def test_one_and_two_ranks_agree():
    """Run on COMM_WORLD and, on rank 0, on COMM_SELF; the time series agree to round-off.

    Meaningful under ``mpirun -n 2`` (on 1 rank the two runs are the same). The mesh is
    the same (built by gmsh on one rank); only the partition and dof numbering differ, so
    the differences are round-off amplified by the solver tolerances (1e-12): we ask 1e-9
    of each column's scale. T = 13 ms covers free flight and the peak of the impact.
    """
    dt, T = 1e-4, 0.013
    par = simulate(disc.problem(level=1, comm=COMM), pair="P2/P1", dt=dt, T=T).timeseries
    ser = None
    if COMM.rank == 0:
        ser = simulate(disc.problem(level=1, comm=MPI.COMM_SELF), pair="P2/P1", dt=dt, T=T).timeseries
    ser = COMM.bcast(ser, root=0)
    assert par["n_active"].max() >= 1
    np.testing.assert_array_equal(par["n_active"], ser["n_active"])
    for c in ("energy", "kinetic", "potential", "u_probe", "lambda_probe", "contact_force", "momentum_y"):
        scale = np.max(np.abs(ser[c]))
        np.testing.assert_allclose(par[c], ser[c], rtol=0, atol=1e-9 * scale, err_msg=c)

