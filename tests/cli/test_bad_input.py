"""Bad input to the run commands: one line, exit 2, nothing written; runs are never overwritten by accident; TOML and the command line."""
import importlib
import json
import re

from mpi4py import MPI
from petsc4py import PETSc

import pytest

from sdm_dolfinx import cli

COMM = MPI.COMM_WORLD
#: the modules whose functions these tests call or replace
memory = importlib.import_module("sdm_dolfinx.run.memory")
planning = importlib.import_module("sdm_dolfinx.run.planning")


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
    (["disc", "--material", "rubber"], None, "invalid choice"),
    (["disc", "--newton", "modified"], None, "--newton modified is the tangent"),
    (["disc"], 'material = "neo-hookean"\nnewton = "quasi"\n', "key 'newton'"),
    (["membrane", "--material", "svk"], None, "vector displacement"),
    (["disc", "--material", "svk", "--scheme", "central-difference", "--pair", "P1/P1", "--mass", "row-sum"], None,
     "no finite-strain step"),
    (["two_balls", "--material", "svk"], None, "contact pairs (the rows between bodies) yet"),
    (["disc", "--spin", "-50"], None, "--spin turns the disc's upper half"),
    (["membrane", "--write-every", "0"], None, "--write-every"),
    (["membrane", "--checkpoint-every", "-3"], None, "--checkpoint-every"),
    (["membrane", "--probe", "2", "0.5"], None, "--probe"),
    (["membrane", "--bogus"], None, "unrecognised"),
    (["block", "--NX", "4"], None, "unrecognised option '--NX'; did you mean --nx?"),
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
    (["membrane", "--restart", "/nonexistent/run"], None, "no run.json"),
    (["membrane", "-sdm_vi_rtol", "-1"], None, "-sdm_vi_rtol"),
    (["membrane", "-sdm_vi_max_it", "0"], None, "-sdm_vi_max_it"),
    (["membrane", "-sdm_vi_max_it", "many"], None, "-sdm_vi_max_it"),
    (["membrane", "-sdm_schur_max_active", "0"], None, "-sdm_schur_max_active"),
    (["ball", "-sdm_schur_max_active", "-3"], None, "-sdm_schur_max_active"),
    (["membrane", "-sdm_gap_max_columns", "-1"], None, "-sdm_gap_max_columns"),
    (["ball", "-sdm_inexact_rtol", "1"], None, "-sdm_inexact_rtol"),
    (["ball", "-sdm_inexact_rtol", "-1e-6"], None, "-sdm_inexact_rtol"),
    (["membrane", "-sdm_inexact_rtol", "0.1"], None, "schur solves every Newton system exactly"),
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
    # runs too large for the machine: refused up front with the memory they would need
    (["membrane", "--N", "10000000"], None, "--N 10000000 needs about"),
    (["membrane", "--N", "2147483648"], None, "--N 2147483648 needs about"),
    (["membrane", "--N", "100000", "--diagonal", "crossed"], None, "--N 100000 --diagonal crossed needs about"),
    (["disc", "--h", "1e-300"], None, "1e-300"),
    (["membrane", "-sdm_snes_max_it", "-5"], None, "-sdm_snes_max_it: '-5' is not an integer >= 1"),
    (["membrane", "-sdm_snes_max_it", "0"], None, "-sdm_snes_max_it"),
    (["membrane", "--out", ""], None, "--out"),
    (["membrane", "--out", "x" * 300], None, "300 characters"),
    (["membrane", "--out", "a/" + "x" * 300 + "/b"], None, "300 characters"),
    (["membrane", "--config", "/dev/zero"], None, "not a regular file"),
    (["membrane", "--config", "/dev/null"], None, "not a regular file"),
    (["membrane"], "#" + "x" * (1 << 20) + "\n", "larger than 1 MB"),
    (["membrane", "--dt", "0.003", "--T", "0.01"], None,
     "T = 0.01 is not a multiple of dt = 0.003: 3 steps end at t = 0.009; give T = 0.009 or 0.012"),
    (["disc", "--dt", "3e-4", "--T", "0.02"], None, "T = 0.02 is not a multiple of dt = 0.0003"),
    (["membrane"], "write-every = 0\n", "bad.toml: key 'write-every': must be an integer >= 1 (got 0)"),
    (["membrane"], "checkpoint-every = -2\n", "bad.toml: key 'checkpoint-every'"),
    (["membrane"], "N = 0\n", "bad.toml: key 'N' (--N) must be >= 1 (got 0)"),
    (["disc"], "radius = -1.0\n", "bad.toml: key 'radius' (--radius) must be > 0"),
    # options that would be accepted, recorded in run.json and do nothing
    (["ball", "--no-contact", "--friction", "coulomb", "--mu", "0.3", "--T", "4e-5"], None,
     "friction coulomb acts at the constrained vertices, and problem 'ball' has none"),
    (["membrane", "--contact", "penalty", "--vi-solver", "vinewtonrsls"], None,
     "contact penalty has its own step solver: remove --vi-solver"),
    (["membrane", "--contact", "penalty", "--vi-solver", "vinewtonssls"], None, "remove --vi-solver"),
    (["disc", "--contact", "nitsche", "--vi-solver", "vinewtonrsls"], None, "remove --vi-solver"),
    (["membrane", "--contact", "penalty", "--linear", "amg"], None, "--linear amg: contact penalty solves its steps"),
    (["disc", "--vi-solver", "vinewtonrsls", "--linear", "cg-pmg"], None,
     "--vi-solver 'vinewtonrsls' takes --linear 'auto' or 'lu' only"),
    (["membrane", "--vi-solver", "vinewtonssls", "--linear", "schur"], None, "and schur is a strategy of the semi"),
    (["membrane", "-sdm_bogus_option", "1"], None, "PETSc option -sdm_bogus_option: no step solver reads it"),
    (["membrane", "-sdm_2_bogus"], None, "PETSc option -sdm_2_bogus: no step solver reads it"),
]


@pytest.mark.parametrize("argv,toml,message", BAD)
def test_bad_input_is_refused(argv, toml, message, mpi_tmp_path, capsys, monkeypatch):
    """Status 2, a one-line message naming the problem, no traceback, nothing written (neither
    in --out nor in the current folder)."""
    out, cwd = mpi_tmp_path / "never", mpi_tmp_path / "cwd"
    if COMM.rank == 0:
        cwd.mkdir()
    COMM.Barrier()
    monkeypatch.chdir(cwd)
    argv = list(argv)
    if toml is not None:
        argv += ["--config", _write(mpi_tmp_path / "bad.toml", toml)]
    if argv[0] in ("membrane", "disc", "ball") and "--out" not in argv:
        argv += ["--out", str(out)]
    try:
        assert cli.main(argv) == 2
    finally:        # a valid -sdm_ option the step solver refused stays in PETSc's database: not for the next test
        for key in (a for a in argv if a.startswith("-sdm_")):
            PETSc.Options().delValue(key[1:])
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert message in err and len(err.strip().splitlines()) == 1, err
        assert "Traceback" not in err
    assert not out.exists() and not list(cwd.iterdir())


def test_too_large_for_this_machine(mpi_tmp_path, capsys, monkeypatch):
    """A run whose estimated memory exceeds what the machine has available is refused with
    both numbers (here the machine is said to have 16 GB: --N 4500 needs ~80 GB with P1+/P0),
    and so is an inf-sup inspection; a run that fits is accepted."""
    monkeypatch.setattr(memory, "available_memory", lambda comm=COMM: 16e9)
    out = mpi_tmp_path / "never"
    assert cli.main(["membrane", "--N", "4500", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert re.fullmatch(r"python -m sdm_dolfinx membrane: error: --N 4500 needs about (\d+) GB \(dim W\^h = "
                            r"6\.1e\+07 with P1\+/P0\), this machine has 16 GB available\n", err), err
        assert 60 <= int(re.search(r"about (\d+) GB", err).group(1)) <= 100
    assert cli.main(["inspect", "--N", "4500"]) == 2
    assert "--N 4500 needs about" in capsys.readouterr().err or COMM.rank != 0
    assert not out.exists()
    plan = planning.plan("membrane", {"N": 200}, out=None)      # ~0.3 GB
    assert plan.spec.name == "membrane"
    with pytest.raises(planning.RunInputError, match=r"^N = 4500 needs about"):
        planning.plan("membrane", {"N": 4500})


def test_steps_are_a_multiple_of_dt():
    """T must be a whole number of steps: the paper's T / dt (multiples up to round-off) are
    accepted, through the API too; the message names both neighbours."""
    for T, dt in ((0.02, 1e-4), (0.02, 1e-5), (0.8, 0.0003125), (0.8, 0.00015625), (0.4, 2.5e-05), (0.8, 0.01),
                  (0.3, 0.1), (0.7, 0.1), (1.0, 1e-3)):
        assert planning.plan("membrane", {"N": 4}, T=T, dt=dt).steps == round(T / dt)
    with pytest.raises(planning.RunInputError, match=r"^T = 0\.01 is not a multiple of dt = 0\.003: 3 steps end at "
                                                    r"t = 0\.009; give T = 0\.009 or 0\.012$"):
        planning.plan("membrane", T=0.01, dt=0.003)


@pytest.mark.parametrize("value", ["-6e-1", "-6E-1", "-.6", "-6.0e-01", "-0.6"])
def test_negative_numbers_in_exponent_notation(value):
    """``--f -6e-1`` is a value, not an option."""
    from sdm_dolfinx.cli import run
    spec, args, extra = run.parse("membrane", ["--f", value, "--obstacle", "-1e-3", "--out", "x"])
    assert args.f == -0.6 and args.obstacle == -1e-3 and extra == []


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
        info = json.loads((out / "run.json").read_text())
        assert info["status"] == "finished"
        import numpy as np              # the checkpoint there is the new run's own, at its end
        with np.load(out / "checkpoint.npz") as f:
            meta = json.loads(str(f["meta"]))
        assert meta["run_id"] == info["run_id"] and meta["step"] == info["steps"] == 2


def test_config_file_and_command_line_override(mpi_tmp_path):
    """A TOML file describes the run; options on the command line win."""
    cfg = _write(mpi_tmp_path / "run.toml", 'problem = "membrane"\npair = "P2/P1"\nN = 4\ndt = 0.01\nT = 0.05\n'
                                            'write-every = 2\nquiet = true\n')
    out = mpi_tmp_path / "out"
    assert cli.main(["membrane", "--config", cfg, "--N", "5", "--out", str(out)]) == 0
    info = json.loads((out / "run.json").read_text()) if COMM.rank == 0 else None
    info = COMM.bcast(info, root=0)
    assert info["pair"] == "P2/P1" and info["problem"]["parameters"]["N"] == 5 and info["steps"] == 5

