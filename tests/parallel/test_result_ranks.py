"""Result's Functions on one rank of several: ``result.displacement()`` (and ``velocity()``,
``vbar()``) called on rank 0 only returns (it hung: a dolfinx Function is created
collectively), with the values the same calls give on every rank."""
import os
import subprocess
import sys
import time

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import simulate

COMM = MPI.COMM_WORLD
pytestmark = pytest.mark.mpi

SCRIPT = """
import sys
import numpy as np
from mpi4py import MPI
from sdm_dolfinx import simulate
comm = MPI.COMM_WORLD
r = simulate("membrane", {"N": 8}, pair="P1+/P0", dt=1e-2, T=0.3)
if comm.rank == 0:                      # rank 0 only: the common mistake
    u, v, w = r.displacement(), r.velocity(), r.vbar()
    n = u.function_space.dofmap.index_map.size_local
    print("rank0", float(np.sum(u.x.array[:n] ** 2)), float(np.sum(v.x.array ** 2) >= 0), flush=True)
comm.Barrier()
total = comm.allreduce(float(np.sum(r.displacement().x.array[:r.discretisation.W.dofmap.index_map.size_local] ** 2)))
if comm.rank == 0:
    print("all", total, flush=True)
"""


@pytest.mark.skipif(COMM.size > 1, reason="starts its own mpirun")
def test_result_functions_on_rank_0_only(tmp_path):
    script = tmp_path / "rank0.py"
    script.write_text(SCRIPT)
    env = {**os.environ, "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_btl": "self,vader", "OMPI_MCA_rmaps_base_oversubscribe": "1"}
    t0 = time.time()
    try:
        p = subprocess.run(["mpirun", "-n", "2", sys.executable, str(script)], capture_output=True, text=True,
                           timeout=90, env=env)
    except subprocess.TimeoutExpired:
        pytest.fail("result.displacement() on rank 0 only hung")
    assert p.returncode == 0, p.stderr
    lines = dict(ln.split(" ", 1) for ln in p.stdout.splitlines() if ln.startswith(("rank0", "all")))
    assert float(lines["rank0"].split()[1]) > 0 and "all" in lines
    assert time.time() - t0 < 90


def test_functions_are_fresh_copies():
    """Each call returns a new Function with the result's values: changing one changes no other."""
    r = simulate("membrane", {"N": 4}, dt=1e-2, T=0.05)
    a, b = r.displacement(), r.displacement()
    n = len(r.U.array)
    assert a is not b and np.array_equal(a.x.array[:n], r.U.array)
    a.x.array[:] = 0.0
    assert np.array_equal(b.x.array[:n], r.U.array) and np.array_equal(r.displacement().x.array[:n], r.U.array)
    assert r.velocity() is not r.velocity() and r.vbar() is not r.vbar()
