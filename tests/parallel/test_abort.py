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



@pytest.mark.skipif(COMM.size > 1, reason="starts its own mpirun")
def test_a_test_failing_on_one_rank_ends_the_run(tmp_path):
    """A test that fails on rank 0 only leaves rank 1 waiting in a collective call: the suite's
    watchdog (tests/conftest.py) prints the failure at once and ends the run a few seconds later,
    instead of the hang that would run a CI job out of time."""
    import shutil
    shutil.copy(os.path.join(os.path.dirname(__file__), os.pardir, "conftest.py"), tmp_path / "conftest.py")
    (tmp_path / "test_one_rank_fails.py").write_text(
        "from mpi4py import MPI\n\n"
        "def test_fails_on_rank_0_only():\n"
        "    comm = MPI.COMM_WORLD\n"
        "    assert comm.rank != 0, 'fails on rank 0 only'\n"
        "    comm.allreduce(1)    # rank 1 waits here for rank 0, which has left the test\n\n"
        "def test_after():\n"
        "    pass\n")
    env = {**os.environ, "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_btl": "self,vader", "OMPI_MCA_rmaps_base_oversubscribe": "1", "SDM_TEST_DESYNC_SECONDS": "3"}
    t0 = time.time()
    p = subprocess.run(["mpirun", "-n", "2", sys.executable, "-m", "mpi4py", "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        "test_one_rank_fails.py"], cwd=tmp_path, capture_output=True, text=True, timeout=180, env=env)
    assert p.returncode != 0
    assert "rank 0: FAILED test_one_rank_fails.py::test_fails_on_rank_0_only (call)" in p.stderr
    assert "fails on rank 0 only" in p.stderr
    assert "did not follow within 3 s" in p.stderr
    assert time.time() - t0 < 90
