"""The 3-D ball on three ranks ("1/2/3 ranks agree"), started with mpirun from a serial
test: ``tests/physics/test_ball.py::test_one_and_two_ranks_agree`` compares the ball run on
COMM_WORLD with the same run on one rank (COMM_SELF); here it runs under ``mpirun -n 3``
(oversubscribed on two cores), so a partition into three parts is compared with one rank, to
the same tolerance (1e-9 of each column's scale). ``make test`` runs the same test under
``mpirun -n 2``.
"""
import os
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI

import pytest

from test_faults_common import MPI_ENV

COMM = MPI.COMM_WORLD
pytestmark = [pytest.mark.mpi, pytest.mark.skipif(COMM.size > 1, reason="starts its own mpirun -n 3")]
BALL_TEST = Path(__file__).resolve().parents[1] / "physics" / "test_ball.py"


@pytest.mark.slow
def test_three_ranks_agree_with_one():
    cmd = ["mpirun", "-n", "3", sys.executable, "-m", "mpi4py", "-m", "pytest", "-q", "-p", "no:cacheprovider",
           f"{BALL_TEST}::test_one_and_two_ranks_agree"]
    # more ranks than cores: Open MPI 4 reads MPI_ENV's OMPI_MCA_rmaps_base_oversubscribe, Open MPI 5
    # (dolfinx 0.9's Debian 13) its PRRTE's mapping policy
    env = {**os.environ, **MPI_ENV, "PRTE_MCA_rmaps_default_mapping_policy": ":oversubscribe"}
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, env=env)
    tail = (r.stdout + r.stderr)[-3000:]
    assert r.returncode == 0, tail
    assert r.stdout.count("1 passed") >= 1, tail
