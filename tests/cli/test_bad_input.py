"""Bad input to the run commands: one line, exit 2, nothing written; runs are never overwritten by accident; TOML and the command line."""
import json

from mpi4py import MPI

import pytest

from sdm_dolfinx import cli

COMM = MPI.COMM_WORLD


def _write(path, text):
    if COMM.rank == 0:
        path.write_bytes(text if isinstance(text, bytes) else text.encode())
    COMM.Barrier()
    return str(path)


# (argv, TOML text or None, expected fragment of the one-line message)
BAD = [
    (["membrane", "--pair", "P3/P0"], None, "invalid choice"),
    (["membrane", "--scheme", "leapfrog"], None, "invalid choice"),
    (["membrane", "--dt", "0"], None, "positive"),
    (["membrane", "--dt=-1e-3"], None, "positive"),
    (["membrane", "--dt", "-1"], None, "positive"),
    (["membrane", "--dt", "nan"], None, "positive"),
    (["membrane", "--T", "inf"], None, "positive"),
    (["membrane", "--dt", "abc"], None, "not a number"),
    (["membrane", "--dt", "0.1", "--T", "0.05"], None, "--T"),
    (["membrane", "--N", "0"], None, "--N"),
    (["membrane", "--N", "-4"], None, "--N"),
    (["membrane", "--N", "2.5"], None, "invalid int"),
    (["membrane", "--pair", "P1+/P0", "--mass", "lumped"], None, "not available"),
    (["membrane", "--write-every", "0"], None, "--write-every"),
    (["membrane", "--checkpoint-every", "-3"], None, "--checkpoint-every"),
    (["membrane", "--probe", "2", "0.5"], None, "--probe"),
    (["membrane", "--bogus"], None, "unrecognised"),
    (["nosuchproblem"], None, "unknown command"),
    (["membrane", "--config", "/nonexistent/run.toml"], None, "not found"),
    (["membrane"], "dt = 1e-3\nNN = 4\n", "unknown key 'NN'"),
    (["membrane"], 'N = "ten"\n', "key 'N': expected an integer"),
    (["membrane"], "N = true\n", "key 'N': expected an integer"),
    (["membrane"], "dt = -0.5\n", "key 'dt'"),
    (["membrane"], "dt = nan\n", "key 'dt'"),
    (["membrane"], 'dt = "small"\n', "key 'dt': expected a number"),
    (["membrane"], 'pair = "Q2/Q1"\n', "key 'pair'"),
    (["membrane"], "probe = [0.5]\n", "key 'probe'"),
    (["membrane"], "overwrite = 1\n", "key 'overwrite'"),
    (["membrane"], "N = 4\ndt = \n", "invalid TOML"),
    (["membrane"], 'problem = "disc"\n', "key 'problem'"),
    (["membrane"], "N = 0\n", "--N"),
    (["membrane", "--restart", "/nonexistent/run"], None, "no run.json"),
    (["membrane", "-sdm_vi_rtol", "-1"], None, "-sdm_vi_rtol"),
    (["membrane", "-sdm_vi_max_it", "0"], None, "-sdm_vi_max_it"),
    (["membrane", "-sdm_vi_max_it", "many"], None, "-sdm_vi_max_it"),
    (["disc", "--radius", "0"], None, "--radius"),
    (["disc", "--rho", "nan"], None, "--rho"),
    (["disc", "--level", "7"], None, "invalid choice"),
    (["disc", "--h", "-1"], None, "--h"),
    (["disc", "--lame-mu", "-150"], None, "--lame-mu"),
    (["disc", "--gravity", "inf"], None, "--gravity"),
    (["disc"], 'problem = "membrane"\n', "key 'problem'"),
    (["disc"], "level = 2.5\n", "key 'level'"),
    (["disc", "--mesh", "/nonexistent/disc.msh"], None, "no such file"),
    (["disc"], 'mesh = "/nonexistent/disc.msh"\n', "no such file"),
    (["disc"], "mesh = 3\n", "key 'mesh'"),
    (["membrane", "--f", "nan"], None, "--f"),
    (["membrane", "--u0", "inf"], None, "--u0"),
    (["membrane", "--obstacle", "nan"], None, "--obstacle"),
    (["membrane"], "g = 1e400\n", "--g"),
    (["membrane", "--dt", "1e-300", "--T", "1"], None, "at most"),
    (["membrane"], "write_every = 2\nwrite-every = 3\n", "same option"),
    (["membrane"], b"\xff\xfe\x00N = 3\n", "not a TOML file"),
]


@pytest.mark.parametrize("argv,toml,message", BAD)
def test_bad_input_is_refused(argv, toml, message, mpi_tmp_path, capsys):
    """Status 2, a one-line message naming the problem, no traceback, nothing written."""
    out = mpi_tmp_path / "never"
    argv = list(argv)
    if toml is not None:
        argv += ["--config", _write(mpi_tmp_path / "bad.toml", toml)]
    if argv[0] in ("membrane", "disc"):
        argv += ["--out", str(out)]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert message in err and len(err.strip().splitlines()) == 1, err
        assert "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("status,checkpoint,message", [
    ("finished", False, "finished run"), ("failed", False, "failed run"),
    ("interrupted", True, "--restart"), ("running", True, "--restart"), ("running", False, "killed")])
def test_unfinished_work_is_not_overwritten(status, checkpoint, message, mpi_tmp_path, capsys):
    """A folder holding a run (finished, failed, interrupted, killed or still going) is
    refused without --overwrite, naming --restart when a checkpoint can continue it; with
    --overwrite the new run replaces it."""
    out = mpi_tmp_path / "run"
    if COMM.rank == 0:
        out.mkdir()
        (out / "run.json").write_text(json.dumps({"status": status}))
        (out / "timeseries.csv").write_text("precious\n")
        if checkpoint:
            (out / "checkpoint.npz").write_bytes(b"state")
    COMM.Barrier()
    argv = ["membrane", "--N", "4", "--dt", "1e-2", "--T", "0.02", "--quiet", "--out", str(out)]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert message in err and len(err.strip().splitlines()) == 1, err
        assert (out / "timeseries.csv").read_text() == "precious\n"
    COMM.Barrier()
    assert cli.main(argv + ["--overwrite"]) == 0
    if COMM.rank == 0:
        assert not (out / "checkpoint.npz").exists()
        assert json.loads((out / "run.json").read_text())["status"] == "finished"


def test_config_file_and_command_line_override(mpi_tmp_path):
    """A TOML file describes the run; options on the command line win."""
    cfg = _write(mpi_tmp_path / "run.toml", 'problem = "membrane"\npair = "P2/P1"\nN = 4\ndt = 0.01\nT = 0.05\n'
                                            'write-every = 2\nquiet = true\n')
    out = mpi_tmp_path / "out"
    assert cli.main(["membrane", "--config", cfg, "--N", "5", "--out", str(out)]) == 0
    info = json.loads((out / "run.json").read_text()) if COMM.rank == 0 else None
    info = COMM.bcast(info, root=0)
    assert info["pair"] == "P2/P1" and info["problem"]["parameters"]["N"] == 5 and info["steps"] == 5

