"""Helpers of the fault tests (test_faults_*.py): run the command line in a separate process
(serially or under mpirun), and compare two run folders file by file. No tests here."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

#: OpenMPI as root, shared-memory transport, oversubscribed 2-core machine (STYLE.md)
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1", "OMPI_MCA_btl": "self,vader",
           "OMPI_MCA_rmaps_base_oversubscribe": "1"}


#: the XDMF fields of the M-formulation runs of these tests (H^h != W^h: Vbar_W beside velocity), sorted
FIELDS = ["Vbar_W", "active", "contact_stress", "displacement", "velocity"]


def command(args, ranks=1):
    """The command line of ``python -m sdm_dolfinx ARGS`` (under mpirun with ``ranks`` > 1)."""
    cmd = [sys.executable, "-m", "sdm_dolfinx", *map(str, args)]
    return (["mpirun", "-n", str(ranks)] + cmd) if ranks > 1 else cmd


def env():
    return {**os.environ, **MPI_ENV}


def run(args, ranks=1, timeout=600):
    """Run the command to its end; the CompletedProcess (text output)."""
    return subprocess.run(command(args, ranks), capture_output=True, text=True, timeout=timeout, env=env())


def start(args, ranks=1):
    """Start the command; the Popen (stderr piped, stdout discarded)."""
    return subprocess.Popen(command(args, ranks), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env=env())


def info(folder):
    return json.loads((folder / "run.json").read_text())


def rows(folder):
    """Number of whole data rows in timeseries.csv (0 if none yet)."""
    try:
        lines = (folder / "timeseries.csv").read_text().splitlines()
    except FileNotFoundError:
        return 0
    return max(len(lines) - 1, 0)


def error_lines(stderr):
    """The lines of stderr that are not warnings."""
    return [ln for ln in stderr.splitlines() if ln.strip() and not ln.startswith("warning:")]


def column_scale(a, csv):
    """Each column's largest |value| in ``a`` (rows of ``csv``), the momenta sharing the larger
    one: a component that is round-off (momentum_x of a head-on impact, ~1e-14) is compared at
    the scale of the momentum, not of its own noise."""
    scale = np.abs(a).max(axis=0)
    names = Path(csv).read_text().splitlines()[0].split(",")
    momenta = [names.index(c) for c in ("momentum_x", "momentum_y") if c in names]
    if momenta:
        scale[momenta] = scale[momenta].max()
    return scale


def assert_same_run(ref, run, atol=0.0):
    """``run`` holds the same files as ``ref``: timeseries.csv, solution.xdmf's XML and every
    field at every time, every row of state.h5. ``atol`` 0: bit for bit (the CSV as text)."""
    from sdm_dolfinx.io.xdmf_reader import read_xdmf
    import h5py
    a = np.loadtxt(ref / "timeseries.csv", delimiter=",", skiprows=1, ndmin=2)
    b = np.loadtxt(run / "timeseries.csv", delimiter=",", skiprows=1, ndmin=2)
    assert a.shape == b.shape, (a.shape, b.shape)
    if atol == 0.0:
        assert (ref / "timeseries.csv").read_text() == (run / "timeseries.csv").read_text()
        assert (ref / "solution.xdmf").read_text() == (run / "solution.xdmf").read_text()
    else:
        assert np.allclose(a, b, rtol=0, atol=atol * column_scale(a, ref / "timeseries.csv"))
    sa, sb = read_xdmf(ref), read_xdmf(run)
    assert sa.times == sb.times and sa.fields == sb.fields == FIELDS
    assert np.array_equal(sa.points, sb.points) and np.array_equal(sa.cells, sb.cells)
    for name in sa.fields:
        for t in sa.times:
            fa, fb = sa.field(name, t), sb.field(name, t)
            assert np.allclose(fa, fb, rtol=0, atol=atol * max(np.abs(fa).max(), 1e-300)), (name, t)
    with h5py.File(ref / "state.h5", "r") as x, h5py.File(run / "state.h5", "r") as y:
        assert np.array_equal(x["step"][:], y["step"][:]) and np.array_equal(x["t"][:], y["t"][:])
        for key in ("W/dof_coordinates", "V_space/dof_coordinates"):
            assert np.array_equal(x[key][:], y[key][:])
        for key in ("U", "V"):
            assert np.allclose(x[key][:], y[key][:], rtol=0, atol=atol * np.abs(x[key][:]).max()), key
    assert info(run)["status"] == "finished"


@pytest.fixture
def small_disc(tmp_path):
    """A 2 MB tmpfs (root only), unmounted afterwards; skips where mounting is not allowed."""
    mnt = tmp_path / "disc"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mnt)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)
