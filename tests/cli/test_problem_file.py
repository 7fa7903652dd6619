"""A user's problem file is first-class: the block of docs/add_a_problem.md, copied from the
page itself, goes through every command the membrane and the disc have (run, TOML, restart,
energy, inspect, render), on 1 and 2 ranks."""
import json
import re
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli
from sdm_dolfinx.run import Interrupted, simulate

COMM = MPI.COMM_WORLD
DOC = Path(__file__).resolve().parents[2] / "docs" / "add_a_problem.md"
SMALL = ["--n", "4", "--dt", "4e-5", "--T", "2.4e-3", "--quiet"]


#: each test's problem file (another folder each time) registers afresh: the registry is restored after
pytestmark = pytest.mark.usefixtures("clean_registry")


def block_file(folder):
    """docs/add_a_problem.md's my_block.py, written into ``folder`` (rank 0) and shared."""
    path = folder / "my_block.py"
    if COMM.rank == 0:
        text = DOC.read_text()
        code = re.search(r"Save as `my_block.py`.*?```python\n(.*?)```", text, re.S).group(1)
        path.write_text(code)
    COMM.Barrier()
    return path


def series(folder):
    text = (folder / "timeseries.csv").read_text() if COMM.rank == 0 else None
    text = COMM.bcast(text, root=0)
    return np.genfromtxt(text.splitlines(), delimiter=",", names=True)


def test_problem_file_round_trip(mpi_tmp_path, capsys):
    f = block_file(mpi_tmp_path)
    ref, cut, cfg_out = mpi_tmp_path / "ref", mpi_tmp_path / "cut", mpi_tmp_path / "cfg"
    # run from the command line, with the declared options
    assert cli.main(["run", "--problem-file", str(f), *SMALL, "--out", str(ref)]) == 0
    a = series(ref)
    assert a["n_active"].max() > 0                                  # it reached the floor
    info = json.loads((ref / "run.json").read_text()) if COMM.rank == 0 else None
    info = COMM.bcast(info, root=0)
    assert info["problem"]["name"] == "my_block" and info["problem"]["source"] == str(f.resolve())
    assert info["problem"]["args"]["n"] == 4 and info["pair"] == "P2/P1"    # the file's default pair
    # bad values of its declared parameters: one line, exit 2, nothing written
    capsys.readouterr()
    assert cli.main(["run", "--problem-file", str(f), "--nu", "0.5", "--out", str(mpi_tmp_path / "bad")]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert "--nu must be <= 0.49" in err and len(err.strip().splitlines()) == 1
    assert not (mpi_tmp_path / "bad").exists()
    # interrupted through the API after step 20, continued from the command line
    with pytest.raises(Interrupted):
        simulate(f, {"n": 4}, out=cut, dt=4e-5, T=2.4e-3, on_step=lambda n, row: n == 20)
    assert cli.main(["run", "--restart", str(cut), "--quiet"]) == 0
    b = series(cut)
    assert len(b) == len(a) == 61
    # the restart continues the run: the same history (round-off of the restored active set)
    for col in ("energy", "u_probe", "contact_force", "momentum_y"):
        scale = np.abs(a[col]).max()
        assert np.allclose(a[col], b[col], rtol=0, atol=1e-9 * scale), col
    # a TOML file naming the problem file
    if COMM.rank == 0:
        (mpi_tmp_path / "block.toml").write_text(f'problem-file = "{f}"\nn = 4\ndt = 4e-5\nT = 4e-4\n')
    COMM.Barrier()
    assert cli.main(["run", "--config", str(mpi_tmp_path / "block.toml"), "--quiet", "--out", str(cfg_out)]) == 0
    assert len(series(cfg_out)) == 11
    # energy from state.h5 through the registry (the declaration is found from run.json)
    assert cli.main(["energy", str(ref)]) == 0
    # inspect on the file's problem
    assert cli.main(["inspect", "--problem-file", str(f), "--n", "2", "--pair", "P2/P1"]) == 0
    # a picture of the deformed block (von Mises from the problem's lame_lambda, lame_mu)
    assert cli.main(["render", str(ref), "--png", str(mpi_tmp_path / "block.png"), "--size", "320", "240"]) == 0
    if COMM.rank == 0:
        assert (mpi_tmp_path / "block.png").stat().st_size > 1000


def test_problem_file_errors_are_one_line(mpi_tmp_path, capsys):
    bad = mpi_tmp_path / "broken.py"
    none = mpi_tmp_path / "nothing.py"
    if COMM.rank == 0:
        bad.write_text("raise RuntimeError('oops')\n")
        none.write_text("x = 1\n")
    COMM.Barrier()
    for argv, message in ((["run", "--problem-file", str(bad)], "RuntimeError: oops"),
                          (["run", "--problem-file", str(none)], "defines no PROBLEM"),
                          (["run", "--problem-file", str(mpi_tmp_path / "absent.py")], "no such file"),
                          (["run"], "choose the problem"),
                          (["run", "--problem", "nosuch"], "unknown problem")):
        capsys.readouterr()
        assert cli.main(argv + ["--out", str(mpi_tmp_path / "never")]) == 2, argv
        err = capsys.readouterr().err
        if COMM.rank == 0:
            assert message in err and len(err.strip().splitlines()) == 1, err
    assert not (mpi_tmp_path / "never").exists()


def _interrupted_run(mpi_tmp_path):
    """docs/add_a_problem.md's block, started from its file and interrupted after step 12 with a
    checkpoint (as a Ctrl-C would leave it): (the file, the run's folder)."""
    f = block_file(mpi_tmp_path)
    cut = mpi_tmp_path / "cut"
    with pytest.raises(Interrupted):
        simulate(str(f), {"n": 4}, out=cut, dt=4e-5, T=2.4e-3, checkpoint_every=5, on_step=lambda n, row: n == 12)
    return f, cut


def test_restart_refuses_a_changed_problem_file(mpi_tmp_path, capsys):
    """The run's physics is its problem file: after the file's stiffness is multiplied by 4, --restart
    refuses in one line naming the file and the deliberate way to continue, and writes nothing (it
    continued with the new physics before: exit 0, the energy jumping by 4.9 with E0 = 3.9)."""
    f, cut = _interrupted_run(mpi_tmp_path)
    before = (cut / "run.json").read_text() if COMM.rank == 0 else None
    if COMM.rank == 0:
        text = f.read_text()
        assert text.count('Param("E", 1000.0') == 1
        f.write_text(text.replace('Param("E", 1000.0', 'Param("E", 4000.0'))
    COMM.Barrier()
    capsys.readouterr()
    assert cli.main(["run", "--restart", str(cut), "--quiet"]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert len(err.strip().splitlines()) == 1, err
        assert f"the problem file {f.resolve()} has changed" in err and "--allow-changed-source" in err
        assert (cut / "run.json").read_text() == before            # nothing written
    with pytest.raises(Exception, match="allow_changed_source=True"):
        simulate(out=cut, restart=True)
    # deliberately: it continues, and run.json says with what
    assert cli.main(["run", "--restart", str(cut), "--quiet", "--allow-changed-source"]) == 0
    if COMM.rank == 0:
        info = json.loads((cut / "run.json").read_text())
        assert info["status"] == "finished" and "has changed" in info["continued_with_changed_source"][0]


def test_a_restart_names_the_one_difference_in_one_line(mpi_tmp_path):
    """A checkpoint of another problem is refused naming the first entry that differs
    (problem.args.E), not the whole problem (a JSON dump of several kB before); and
    allow_changed_source belongs to restarts only."""
    from sdm_dolfinx.problems import load_file
    f, cut = _interrupted_run(mpi_tmp_path)
    spec = load_file(f)
    with pytest.raises(Exception) as e:
        simulate(spec.problem(COMM, n=4, E=2000.0), out=cut, restart=True, dt=4e-5, T=2.4e-3, checkpoint_every=5)
    msg = str(e.value)
    assert type(e.value).__name__ == "CheckpointError" and len(msg.splitlines()) == 1 and len(msg) < 200, msg
    assert "problem.args.E = 1000.0" in msg and "2000.0" in msg
    with pytest.raises(Exception, match="for a restart only"):
        simulate(str(f), {"n": 4}, dt=4e-5, T=2.4e-3, allow_changed_source=True)
