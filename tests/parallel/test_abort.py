"""An exception on one rank takes every rank down at once (no hang)."""
import os
import subprocess
import sys
import time

from mpi4py import MPI

import pytest

COMM = MPI.COMM_WORLD
pytestmark = pytest.mark.mpi


@pytest.mark.skipif(COMM.size > 1, reason="starts its own mpirun")
def test_exception_on_one_rank_aborts_every_rank(tmp_path):
    """An unexpected exception on rank 1 only (injected into the probe) takes both ranks
    down at once: one line naming the rank, a non-zero status, no hang."""
    script = tmp_path / "inject.py"
    script.write_text(
        "import sys\nfrom mpi4py import MPI\nfrom sdm_dolfinx import cli\nfrom sdm_dolfinx.run import probes as output\n"
        "orig, n = output.PointProbe.__call__, [0]\n"
        "def bad(self, U):\n    n[0] += 1\n"
        "    if MPI.COMM_WORLD.rank == 1 and n[0] == 6:\n        raise RuntimeError('injected on rank 1')\n"
        "    return orig(self, U)\n"
        "output.PointProbe.__call__ = bad\nsys.exit(cli.main(sys.argv[1:]))\n")
    env = {**os.environ, "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_btl": "self,vader", "OMPI_MCA_rmaps_base_oversubscribe": "1"}
    t0 = time.time()
    p = subprocess.run(["mpirun", "-n", "2", sys.executable, str(script), "membrane", "--N", "8", "--dt", "1e-2",
                        "--T", "0.3", "--quiet", "--out", str(tmp_path / "run")],
                       capture_output=True, text=True, timeout=240, env=env)
    assert p.returncode != 0
    assert "internal error on rank 1: RuntimeError: injected on rank 1" in p.stderr
    assert "Traceback" not in p.stderr
    assert time.time() - t0 < 120

