"""Commands that read or write a run folder while a run is in progress there (its folder lock is
held): ``energy`` says the run is in progress instead of failing on a file being written;
``inspect --json`` refuses to write into it (it overwrote the live run's run.json) and onto a
file of a finished run; a --json that cannot be written (/proc) is one line, not an internal
error."""
import json

from mpi4py import MPI

import pytest

from sdm_dolfinx import cli, simulate

COMM = MPI.COMM_WORLD


def one_line(capsys):
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err and "internal error" not in err, err
    return err


def during_a_run(folder, command, at=5):
    """Run ``command`` (a list of cli.main arguments) from on_step at step ``at`` of a membrane run
    writing ``folder``; returns its exit status (the run continues and finishes)."""
    status = []

    def on_step(n, row):
        if n == at:
            status.append(cli.main(command))
    simulate("membrane", {"N": 4}, out=folder, dt=0.01, T=0.1, write_every=2, on_step=on_step)
    return status[0]


def test_energy_says_the_run_is_in_progress(mpi_tmp_path, capsys):
    out = mpi_tmp_path / "run"
    assert during_a_run(out, ["energy", str(out)]) == 2
    err = one_line(capsys)
    if COMM.rank == 0:
        assert f"{out} holds a run in progress (pid " in err and "wait for it to end" in err, err
        assert not (out / "energy_recomputed.csv").exists()
    assert cli.main(["energy", str(out)]) == 0              # finished: it works


def test_inspect_json_refuses_a_live_runs_folder(mpi_tmp_path, capsys):
    out = mpi_tmp_path / "run"
    target = out / "run.json"
    assert during_a_run(out, ["inspect", "--N", "4", "--json", str(target)]) == 2
    err = one_line(capsys)
    if COMM.rank == 0:
        assert f"--json {target}: {out} holds a run in progress" in err, err
        info = json.loads(target.read_text())               # the run's own record, intact
        assert info["status"] == "finished" and "results" not in info
    # a finished run's files are not overwritten either; another file in its folder is fine
    assert cli.main(["inspect", "--N", "4", "--json", str(target)]) == 2
    err = one_line(capsys)
    if COMM.rank == 0:
        assert f"--json {target} is the run.json of the run in {out}: choose another file" in err, err
    assert cli.main(["inspect", "--N", "4", "--json", str(out / "beta.json")]) == 0


@pytest.mark.parametrize("target", ["/proc/x.json", "/proc/self/x/y.json"])
def test_inspect_json_that_cannot_be_written(target, capsys):
    assert cli.main(["inspect", "--N", "4", "--json", target]) == 2
    err = one_line(capsys)
    if COMM.rank == 0:
        assert f"cannot write --json {target}" in err, err
