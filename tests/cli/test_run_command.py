"""The run command's outputs, and bad input refused in one line with status 2."""
import csv
import json
import os
import subprocess
import sys

from mpi4py import MPI

import pytest

from sdm_dolfinx import cli

COMM = MPI.COMM_WORLD
HEADER = "step,t,energy,kinetic,potential,u_probe,lambda_probe,n_active,newton_its,gap_min_boundary"


def test_run_writes_csv_json_and_xdmf(mpi_tmp_path):
    out = mpi_tmp_path / "run"
    status = cli.main(["membrane", "--N", "6", "--dt", "0.01", "--T", "0.3", "--out", str(out), "--quiet",
                       "--write-every", "5"])
    assert status == 0
    if COMM.rank == 0:
        lines = (out / "timeseries.csv").read_text().splitlines()
        assert lines[0] == HEADER
        rows = list(csv.DictReader(lines))
        assert [int(r["step"]) for r in rows] == list(range(31))          # row 0 = initial state
        info = json.loads((out / "run.json").read_text())
        assert info["status"] == "finished" and info["ranks"] == COMM.size
        assert info["dim_W"] == 7 * 7 + 2 * 36 and info["dim_H"] == 2 * 36   # P1+ / P0 on 6x6 squares
        assert "dolfinx" in info["versions"] and info["wall_time"] > 0
        assert (out / "solution.xdmf").stat().st_size > 0 and (out / "solution.h5").stat().st_size > 0
    # a finished run is not overwritten without --overwrite
    assert cli.main(["membrane", "--out", str(out), "--quiet"]) == 2


def test_unwritable_output_folder(mpi_tmp_path, capsys):
    blocker = mpi_tmp_path / "a_file"
    if COMM.rank == 0:
        blocker.write_text("not a folder")
    COMM.Barrier()
    assert cli.main(["membrane", "--out", str(blocker / "sub"), "--quiet"]) == 2
    if COMM.rank == 0:
        assert "cannot write" in capsys.readouterr().err
    # a file system that refuses files even to root (os.access says yes there)
    for path in ("/proc/sdm_out", "/sys/sdm_out"):
        assert cli.main(["membrane", "--out", path, "--quiet"]) == 2
        if COMM.rank == 0:
            err = capsys.readouterr().err
            assert "cannot write" in err and len(err.strip().splitlines()) == 1


@pytest.mark.skipif(COMM.size > 1, reason="starts its own python process: serial only")
def test_no_traceback_from_a_real_process(tmp_path):
    env = dict(os.environ)
    p = subprocess.run([sys.executable, "-m", "sdm_dolfinx", "membrane", "--dt", "-1", "--out", str(tmp_path / "x")],
                       capture_output=True, text=True, env=env, timeout=120)
    assert p.returncode == 2
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
    h = subprocess.run([sys.executable, "-m", "sdm_dolfinx", "membrane", "--help"], capture_output=True, text=True,
                       timeout=120)
    assert h.returncode == 0 and "--pair" in h.stdout and "--dt" in h.stdout


@pytest.mark.skipif(COMM.size > 1, reason="starts its own python processes: serial only")
@pytest.mark.parametrize("option,message", [
    (["-sdm_ksp_type", "nonsense"], "Unable to find requested KSP type nonsense"),
    (["-sdm_ksp_max_it", "abc"], "Input string abc has no integer value"),
    (["-sdm_factor_pc_factor_mat_solver_type", "nonsense"], "Could not locate solver type nonsense")])
def test_petsc_rejecting_an_option_is_bad_input(option, message, tmp_path):
    """A -sdm_ option PETSc refuses stops the run before anything is written, with status 2
    and PETSc's own reason in one line (a separate process: PETSc's options database would
    otherwise keep the bad option for the following tests)."""
    out = tmp_path / "x"
    p = subprocess.run([sys.executable, "-m", "sdm_dolfinx", "membrane", "--N", "4", "--T", "0.02", "--dt", "1e-2",
                        "--quiet", "--out", str(out), *option], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr
    assert message in p.stderr and "check the -sdm_ options" in p.stderr
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert not out.exists()

