"""Runs on 2 ranks that are interrupted and restarted (item 2 of "Reliability II"), started
with mpirun from a serial test: the restarted process partitions the mesh anew (the
partitioner is not reproducible from one process to the next), and every file must still
mean the same thing: state.h5's rows match its dof coordinates (the energy recomputed from
it is the time series'), the XDMF fields match the XDMF mesh (the value at the centre is
u_probe). Also: a full disc on 2 ranks fails in one line, without a hang.
"""
import signal
import subprocess
import time

from mpi4py import MPI

import numpy as np
import pytest

from test_faults_common import error_lines, info, rows, run, small_disc, start  # noqa: F401  (small_disc: a fixture)

COMM = MPI.COMM_WORLD
pytestmark = [pytest.mark.mpi, pytest.mark.skipif(COMM.size > 1, reason="starts its own mpirun")]


def _check_consistent(out):
    """state.h5 and solution.xdmf agree with timeseries.csv at every stored step."""
    from sdm_dolfinx.io.xdmf_reader import read_xdmf
    ts = np.genfromtxt(out / "timeseries.csv", delimiter=",", names=True)
    r = run(["energy", out])
    assert r.returncode == 0, r.stderr
    e = np.genfromtxt(out / "energy_recomputed.csv", delimiter=",", names=True)
    steps = e["step"].astype(int)
    assert len(steps) == len(read_xdmf(out).times)
    # round-off (the energy command measures ~1 eps of its round-off scale, ~4e-11 relative
    # after 2000 steps; the fault this guards against was 1.6e4 relative)
    assert np.allclose(e["energy"], ts["energy"][steps], rtol=1e-9, atol=0)
    s = read_xdmf(out)
    centre = int(np.argmin(np.linalg.norm(s.points[:, :2] - 0.5, axis=1)))
    for t in s.times:
        n = int(round(t / 1e-3))
        assert abs(s.field("displacement", t)[centre] - ts["u_probe"][n]) <= 1e-15, t


@pytest.mark.slow
def test_restart_on_two_ranks_writes_partition_independent_files(tmp_path):
    """mpirun -n 2: SIGINT during contact (mpirun passes it on), mpirun -n 2 --restart, then
    the files are consistent with each other; the restarted run agrees with an uninterrupted
    serial run to round-off."""
    out, ref = tmp_path / "run", tmp_path / "ref"
    args = ["membrane", "--N", "16", "--T", "2", "--write-every", "20", "--quiet"]
    p = start(args + ["--out", out], ranks=2)
    while p.poll() is None and rows(out) < 280:
        time.sleep(0.01)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    i = info(out)
    assert i["status"] == "interrupted" and 280 <= i["interrupted_at_step"] < 2000, err
    r = run(["membrane", "--restart", out, "--quiet"], ranks=2)
    assert r.returncode == 0, r.stderr
    assert info(out)["status"] == "finished"
    _check_consistent(out)
    assert run(args + ["--out", ref]).returncode == 0
    a = np.loadtxt(ref / "timeseries.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1)
    assert a.shape == b.shape and np.allclose(a, b, rtol=0, atol=1e-9 * np.abs(a).max(axis=0))
    import h5py
    with h5py.File(ref / "solution.h5") as x, h5py.File(out / "solution.h5") as y:
        # the XDMF mesh is the same on 1 and 2 ranks (input node order), whatever the partition
        assert np.array_equal(x["Mesh/mesh/geometry"][:], y["Mesh/mesh/geometry"][:])
        assert np.array_equal(x["Mesh/mesh/topology"][:], y["Mesh/mesh/topology"][:])
        for key in x["Function/displacement"]:
            assert np.allclose(x["Function/displacement"][key][:], y["Function/displacement"][key][:],
                               rtol=0, atol=1e-10), key



def test_full_disc_on_two_ranks_fails_in_one_line(small_disc):
    out = small_disc / "run"
    r = run(["membrane", "--N", "16", "--T", "0.5", "--write-every", "1", "--checkpoint-every", "7", "--quiet",
             "--out", out], ranks=2, timeout=300)
    lines = [ln for ln in error_lines(r.stderr) if not ln.startswith("---") and "mpirun" not in ln.lower()]
    assert r.returncode != 0 and "no space left on device while writing" in r.stderr, r.stderr
    assert sum("error" in ln for ln in lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert info(out)["status"] == "failed"
