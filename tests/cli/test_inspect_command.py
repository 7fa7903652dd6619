"""The inspect command: JSON, sweeps and pictures, one-line refusals."""
import json
import math
import re
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI

import pytest

from sdm_dolfinx import cli
from sdm_dolfinx.analysis import TOL

COMM = MPI.COMM_WORLD


# ------------------------------------------------------------------------------- command line
def test_command_line_writes_json(mpi_tmp_path, capsys):
    out = mpi_tmp_path / "inspect.json"
    rc = cli.main(["inspect", "--problem", "membrane", "--pair", "P2/P1", "P1/P0", "--N", "4", "--json", str(out)])
    assert rc == 0
    COMM.Barrier()
    doc = json.loads(out.read_text())
    assert doc["ranks"] == COMM.size and doc["tolerance"] == TOL
    (p2p1, p1p0) = doc["results"]
    assert p2p1["pair"] == "P2/P1" and p2p1["verdict"] == "well-posed"
    assert (p2p1["dim_W"], p2p1["dim_H"], p2p1["N_g"]) == (49, 25, 9)
    assert p1p0["verdict"] == "ill-posed" and "Ker(B) = {0}" in p1p0["reason"]
    if COMM.rank == 0:
        text = capsys.readouterr().out
        assert "beta (condition (7)" in text and "verdict: WELL-POSED" in text and "verdict: ILL-POSED" in text


def test_sweep_prints_table_and_writes_png(mpi_tmp_path, capsys):
    png, js = mpi_tmp_path / "beta.png", mpi_tmp_path / "sweep.json"
    rc = cli.main(["inspect", "--pair", "P1+/P0", "P1+/P1", "--sweep", "2", "4", "--png", str(png), "--json", str(js)])
    assert rc == 0
    COMM.Barrier()
    rows = json.loads(js.read_text())["results"]
    assert [(r["pair"], r["sweep_value"]) for r in rows] == [("P1+/P0", 2), ("P1+/P1", 2), ("P1+/P0", 4),
                                                             ("P1+/P1", 4)]
    assert rows[2]["h"] == pytest.approx(math.sqrt(2) / 4)
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"
    if COMM.rank == 0:
        text = capsys.readouterr().out
        assert "dim Ker B" in text and "well-posed" in text and "ill-posed" in text


@pytest.mark.parametrize("argv, message", [
    (["--pair", "P9/P9"], "unknown pair 'P9/P9'"),
    (["--N", "0"], "--N must be >= 1"),
    (["--sweep", "0"], "must be an integer >= 1"),
    (["--problem", "nope"], "invalid choice"),
    (["--png", "x.png"], "--png needs --sweep"),
    (["--tol", "-1"], "must be a finite number >= 0"),
    (["--bogus"], "unrecognized arguments"),
    (["--N", "100000"], "--N 100000 needs about"),
    (["--N", "2147483648"], "--N 2147483648 needs about"),
    (["--sweep", "4", "2000000"], "--sweep 2000000: --N 2000000 needs about"),
    (["--problem", "disc", "--h", "1e-300"], "1e-300"),
])
def test_bad_input_one_line_exit_2(argv, message, capsys):
    assert cli.main(["inspect", *argv]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("python -m sdm_dolfinx inspect: error:")
        assert message in err and "Traceback" not in err


def test_json_path_that_is_a_folder(mpi_tmp_path, capsys):
    assert cli.main(["inspect", "--json", str(mpi_tmp_path)]) == 2
    if COMM.rank == 0:
        assert "is a folder" in capsys.readouterr().err


@pytest.mark.skipif(COMM.size > 1, reason="spawns a serial process")
def test_no_traceback_from_a_real_process():
    p = subprocess.run([sys.executable, "-m", "sdm_dolfinx", "inspect", "--pair", "P9/P9"], capture_output=True,
                       text=True, cwd=Path(__file__).resolve().parents[2])
    assert p.returncode == 2
    assert p.stderr.startswith("python -m sdm_dolfinx inspect: error:") and "Traceback" not in p.stderr



def test_positional_problem_is_a_deprecated_alias(capsys):
    """``inspect NAME`` still works, with a one-line note on stderr; ``--problem NAME`` is the spelling."""
    assert cli.main(["inspect", "--problem", "membrane", "--N", "4", "--pair", "P1+/P0"]) == 0
    new = capsys.readouterr()
    assert cli.main(["inspect", "membrane", "--N", "4", "--pair", "P1+/P0"]) == 0
    old = capsys.readouterr()
    if COMM.rank == 0:
        def untimed(out):  # the report's wall-clock times, e.g. "(0.01 s)", vary from call to call
            return re.sub(r"\(\d+(\.\d+)? s\)", "(s)", out)
        assert new.err == "" and untimed(old.out) == untimed(new.out) and "beta" in new.out
        assert old.err == ("python -m sdm_dolfinx inspect: note: 'inspect membrane' is deprecated: write "
                           "'inspect --problem membrane'\n")
