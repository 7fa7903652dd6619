"""Faults of the run folder (items 3-6 of "Reliability II"): a second process, a full disc,
files deleted or damaged during a run or before a restart, signals before the first step.

Each fault is reported in one line, ``run.json`` says what happened, and nothing else is
lost: the other files stay readable and a restart (where one makes sense) continues the run.
The API tests run on 1 and 2 ranks; the command-line ones start their own processes.
"""
import json
import signal
import subprocess
import time

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli, membrane, simulate
from sdm_dolfinx.run import Interrupted, RunInputError, plan
from sdm_dolfinx.io import CheckpointError
from sdm_dolfinx.io.folder import FolderInUseError, FolderLock
from sdm_dolfinx.io.run_files import RunFileError
from test_faults_common import (assert_same_run, error_lines, info, rows, run, small_disc,  # noqa: F401 (fixture)
                                start)

COMM = MPI.COMM_WORLD
serial_only = pytest.mark.skipif(COMM.size > 1, reason="starts separate serial processes")
KW = dict(pair="P1+/P0", dt=2e-3, T=0.1, write_every=5)


def on_rank0(func, *args):
    if COMM.rank == 0:
        func(*args)
    COMM.Barrier()


def read_json(path):
    return COMM.bcast(json.loads(path.read_text()) if COMM.rank == 0 else None, root=0)


def snapshot(folder):
    """Every file's bytes (rank 0's view, on every rank)."""
    data = {f.name: f.read_bytes() for f in sorted(folder.iterdir()) if f.is_file()} if COMM.rank == 0 else None
    return COMM.bcast(data, root=0)


# ------------------------------------------------------------------- item 3: two processes
def test_a_held_lock_refuses_the_run_and_writes_nothing(mpi_tmp_path):
    """While another process (here: another open file description) holds the folder's lock,
    a run or a restart into it is refused in one line (a run: RunInputError when its folder is
    checked, as for a declared problem; a restart: FolderInUseError when it takes the lock; the
    command line maps both to exit status 2) and writes nothing; a stale lock file is no lock."""
    out = mpi_tmp_path / "run"
    held = FolderLock(out, COMM)
    try:
        for restart, error in ((False, RunInputError), (True, FolderInUseError)):
            with pytest.raises(error) as e:
                simulate(membrane.problem(N=6), out=out, restart=restart, **KW)
            assert "in use by another run (pid" in str(e.value) and "\n" not in str(e.value)
        assert sorted(f.name for f in out.iterdir()) == [".lock"]
        with pytest.raises(RunInputError, match="in use by another run"):
            plan("membrane", {"N": 6}, out=out, overwrite=True, comm=COMM)
    finally:
        held.release()
    on_rank0((out / ".lock").write_text, "pid 1 on a host that died\n")     # stale: nobody holds it
    r = simulate(membrane.problem(N=6), out=out, **KW)
    assert r.info["status"] == "finished"


@serial_only
def test_restart_of_a_running_run_is_refused_and_the_run_goes_on(tmp_path):
    """--restart (or --overwrite) of a run that is still going: refused in one line with exit
    status 2. The original run is untouched: it is still going, and stops cleanly on SIGTERM
    with whole files (then --restart would continue it)."""
    args = ["membrane", "--N", "12", "--T", "5", "--write-every", "10", "--checkpoint-every", "50", "--quiet"]
    out = tmp_path / "run"
    p = start(args + ["--out", out])
    while p.poll() is None and not (out / "checkpoint.npz").exists():
        time.sleep(0.01)
    for second in (["membrane", "--restart", out], args + ["--out", out, "--overwrite"]):
        r = run(second)
        assert r.returncode == 2 and len(error_lines(r.stderr)) == 1, r.stderr
        assert "in use by another run (pid" in r.stderr
        assert p.poll() is None, "the original run should still be going"
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 128 + signal.SIGTERM, err
    i = info(out)
    assert i["status"] == "interrupted" and rows(out) == i["interrupted_at_step"] + 1
    from sdm_dolfinx.io.checkpoint import readable_h5
    assert readable_h5(out / "solution.h5") and readable_h5(out / "state.h5")
    assert cli.main(["energy", str(out)]) == 0          # state.h5 agrees with the time series


@serial_only
@pytest.mark.slow
def test_two_runs_started_at_once_into_a_new_folder(tmp_path):
    """Two runs started at the same moment into one new folder: one runs, the other is
    refused in one line (exit 2) without touching anything; the folder ends finished, with
    the files of an uninterrupted run."""
    args = ["membrane", "--N", "8", "--T", "0.3", "--write-every", "1", "--quiet"]
    out, ref = tmp_path / "run", tmp_path / "ref"
    ps = [start(args + ["--out", out]) for _ in range(2)]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in ps]
    codes = sorted(rc for rc, _ in results)
    assert codes == [0, 2], results
    err = next(e for rc, e in results if rc == 2)
    assert len(error_lines(err)) == 1 and any(m in err for m in (
        "in use by another run", "holds a run", "written by another run since this one was checked")), err
    assert run(args + ["--out", ref]).returncode == 0
    assert_same_run(ref, out)


# ---------------------------------------------------------------------- item 4: full disc
@serial_only
@pytest.mark.slow
def test_full_disc_fails_in_one_line_and_restarts_once_there_is_space(small_disc, tmp_path):
    """--out on a 2 MB tmpfs: one line ("no space left on device while writing ..."), exit
    status 1, run.json "failed"; every file is readable at the last good step. Once the
    disc is larger, --restart finishes the run, identical to an uninterrupted one."""
    args = ["membrane", "--N", "16", "--T", "0.5", "--write-every", "1", "--checkpoint-every", "7", "--quiet"]
    out = small_disc / "run"
    r = run(args + ["--out", out])
    assert r.returncode == 1, r.stderr
    lines = error_lines(r.stderr)
    assert len(lines) == 1 and "no space left on device while writing" in lines[0], r.stderr
    assert "HDF5" not in r.stderr and "Traceback" not in r.stderr
    i = info(out)
    assert i["status"] == "failed" and "no space left" in i["error"] and i["last_good_step"] > 7
    from sdm_dolfinx.io.xdmf_reader import read_xdmf
    from sdm_dolfinx.io.checkpoint import readable_h5
    assert readable_h5(out / "solution.h5") and readable_h5(out / "state.h5") and len(read_xdmf(out).times) > 7
    assert len((out / "timeseries.csv").read_text().splitlines()) == i["last_good_step"] + 2
    again = run(["membrane", "--restart", out, "--quiet"])                 # still full: the same one line
    assert again.returncode == 1 and len(error_lines(again.stderr)) == 1, again.stderr
    subprocess.run(["mount", "-o", "remount,size=64m", str(small_disc)], check=True)
    r = run(["membrane", "--restart", out, "--quiet"])
    assert r.returncode == 0, r.stderr
    assert run(args + ["--out", tmp_path / "ref"]).returncode == 0
    assert_same_run(tmp_path / "ref", out)


# ------------------------------------------------------ item 5: files deleted during a run
@pytest.mark.parametrize("name", ["timeseries.csv", "solution.xdmf", "solution.h5", "state.h5"])
def test_a_file_deleted_during_the_run_stops_it_in_one_line(mpi_tmp_path, name):
    """A file deleted at step 12: the run stops at its next write of that file with one line
    naming it, run.json says "failed" with the last good step, and the other files hold
    every step up to there."""
    out = mpi_tmp_path / "run"

    def delete(n, row):
        if n == 12:
            on_rank0((out / name).unlink)
    with pytest.raises(RunFileError) as e:
        simulate(membrane.problem(N=6), out=out, checkpoint_every=7, on_step=delete, **KW)
    msg = str(e.value)
    assert msg == f"{out / name} was deleted or replaced during the run"
    i = read_json(out / "run.json")
    assert i["status"] == "failed" and i["error"] == msg
    # noticed at the next write of that file: a row (13), the checkpoint of step 14 (the HDF5
    # files' sizes), the fields of step 15 (the XML: step 15's row and state.h5 row are taken
    # back out, so every file ends at step 14; it ended at 15 with state.h5 at 10)
    last = {"timeseries.csv": 12, "solution.h5": 14, "state.h5": 14, "solution.xdmf": 14}[name]
    assert i["last_good_step"] == last
    if COMM.rank == 0:
        from sdm_dolfinx.io.xdmf_reader import read_xdmf
        from sdm_dolfinx.io.checkpoint import readable_h5
        if name != "timeseries.csv":
            assert len((out / "timeseries.csv").read_text().splitlines()) == last + 2
        if name not in ("solution.xdmf", "solution.h5"):
            assert np.isclose(read_xdmf(out).times[-1], 10 * 2e-3)
        if name != "state.h5":
            import h5py
            with h5py.File(out / "state.h5") as h5:
                assert list(h5["step"][:]) == [0, 5, 10]
        for other in {"solution.h5", "state.h5"} - {name}:
            assert readable_h5(out / other)


@serial_only
def test_deleted_timeseries_reported_by_the_command_line(tmp_path):
    """The command line: one line, exit status 1, and no "wrote .../timeseries.csv"."""
    out = tmp_path / "run"
    p = start(["membrane", "--N", "8", "--T", "0.6", "--write-every", "1", "--out", out])
    while p.poll() is None and rows(out) < 50:
        time.sleep(0.005)
    (out / "timeseries.csv").unlink()
    _, err = p.communicate(timeout=120)
    assert p.returncode == 1 and len(error_lines(err)) == 1, err
    assert "timeseries.csv was deleted or replaced during the run" in err
    assert info(out)["status"] == "failed"


# --------------------------------------------------- item 5: damaged files before a restart
def _interrupted(out, stop=23, **kw):
    with pytest.raises(Interrupted):
        simulate(membrane.problem(N=6), out=out, checkpoint_every=7, on_step=lambda n, row: n == stop,
                 **{**KW, **kw})


def _truncate(path):
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _bad_crc(path):
    """Flip one byte of the first stored array's data: the zip CRC no longer matches."""
    data = bytearray(path.read_bytes())
    i = data.index(b"U.npy") + 200              # inside U's data
    data[i] ^= 0xFF
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("damage", [_truncate, _bad_crc, lambda p: p.write_bytes(b"not a zip")])
def test_damaged_checkpoint_is_refused_in_one_line_and_nothing_changes(mpi_tmp_path, damage):
    out = mpi_tmp_path / "run"
    _interrupted(out)
    on_rank0(damage, out / "checkpoint.npz")
    before = snapshot(out)
    with pytest.raises(CheckpointError) as e:
        simulate(membrane.problem(N=6), out=out, restart=True, **KW)
    assert str(e.value).startswith(f"cannot read {out / 'checkpoint.npz'}") and "\n" not in str(e.value)
    after = snapshot(out)
    assert {k: v for k, v in after.items() if k != ".lock"} == {k: v for k, v in before.items() if k != ".lock"}


@serial_only
def test_damaged_checkpoint_from_the_command_line(tmp_path):
    out = tmp_path / "run"
    assert cli.main(["membrane", "--N", "6", "--T", "0.2", "--checkpoint-every", "7", "--quiet", "--out",
                     str(out)]) == 0
    (out / "run.json").write_text(json.dumps({**info(out), "status": "interrupted"}))
    _bad_crc(out / "checkpoint.npz")
    r = run(["membrane", "--restart", out])
    assert r.returncode == 2 and len(error_lines(r.stderr)) == 1, r.stderr
    assert "cannot read" in r.stderr and "internal error" not in r.stderr


@pytest.mark.parametrize("name", ["solution.h5", "state.h5", "solution.xdmf"])
def test_restart_without_a_field_file_continues_in_a_new_one(mpi_tmp_path, name):
    """A field file deleted before the restart: one warning line, the fields go on in a new
    file from the checkpoint (solution.xdmf alone is rebuilt whole from solution.h5); the
    time series is complete."""
    out = mpi_tmp_path / "run"
    _interrupted(out)
    on_rank0((out / name).unlink)
    r = simulate(membrane.problem(N=6), out=out, restart=True, checkpoint_every=7, **KW)
    assert r.info["status"] == "finished"
    if COMM.rank == 0:
        from sdm_dolfinx.io.xdmf_reader import read_xdmf
        import h5py
        times = read_xdmf(out).times
        assert np.isclose(times[-1], 0.1)
        assert np.isclose(times[0], 0.0 if name != "solution.h5" else 25 * 2e-3)
        with h5py.File(out / "state.h5") as h5:
            assert h5["step"][0] == (23 if name == "state.h5" else 0)
        assert np.array_equal(np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1)[:, 0], np.arange(51))


def test_restart_without_the_time_series_is_refused(mpi_tmp_path):
    out = mpi_tmp_path / "run"
    _interrupted(out)
    on_rank0((out / "timeseries.csv").unlink)
    with pytest.raises(CheckpointError, match="timeseries.csv is missing"):
        simulate(membrane.problem(N=6), out=out, restart=True, **KW)


@pytest.mark.parametrize("text", ["{\"status\": \"fini", "[]", "\x00\xff"])
def test_unreadable_run_json_is_never_overwritten(mpi_tmp_path, text):
    """A damaged run.json (cut short, a JSON list, binary): a new run without --overwrite is
    refused, and so is a restart, in one line."""
    out = mpi_tmp_path / "run"
    simulate(membrane.problem(N=6), out=out, **KW)
    on_rank0((out / "run.json").write_bytes, text.encode("latin-1"))
    with pytest.raises(RunInputError) as e:
        plan("membrane", {"N": 6}, out=out, comm=COMM)
    assert "use --overwrite" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(RunInputError) as e:
        plan(out=out, restart=True, comm=COMM)
    assert "run.json" in str(e.value) and "\n" not in str(e.value)


@serial_only
def test_run_json_holding_a_list_from_the_command_line(tmp_path):
    out = tmp_path / "run"
    assert cli.main(["membrane", "--N", "6", "--T", "0.05", "--quiet", "--out", str(out)]) == 0
    (out / "run.json").write_text("[]")
    for args in (["membrane", "--N", "6", "--T", "0.05", "--out", out], ["membrane", "--restart", out]):
        r = run(args)
        assert r.returncode == 2 and len(error_lines(r.stderr)) == 1 and "Traceback" not in r.stderr, r.stderr


# --------------------------------------------------------- item 6: signals before the loop
def _signal_during(monkeypatch, where):
    """Send SIGINT to this process from inside ``where`` (a method of the run's set-up or
    files), once, on rank 0."""
    import importlib
    module, cls, meth = where.rsplit(".", 2)
    klass = getattr(importlib.import_module(module), cls)
    orig, sent = getattr(klass, meth), []

    def wrapped(self, *args, **kwargs):
        out = orig(self, *args, **kwargs)
        if not sent and COMM.rank == 0:
            sent.append(1)
            signal.raise_signal(signal.SIGINT)
        return out
    monkeypatch.setattr(klass, meth, wrapped)


def test_sigint_during_set_up_stops_before_anything_is_written(mpi_tmp_path, monkeypatch):
    out = mpi_tmp_path / "run"
    _signal_during(monkeypatch, "sdm_dolfinx.run.integrator.Integrator.initial_velocity")
    with pytest.raises(Interrupted, match="before anything was written") as e:
        simulate(membrane.problem(N=6), out=out, handle_signals=True, **KW)
    assert e.value.signum == signal.SIGINT
    assert not out.exists()


def test_sigint_while_the_files_are_created_leaves_a_restartable_run(mpi_tmp_path, monkeypatch):
    """A SIGINT while the files are being created: the run stops at step 0 with a checkpoint
    (run.json "interrupted"), and its restart is the uninterrupted run."""
    out = mpi_tmp_path / "run"
    simulate(membrane.problem(N=6), out=mpi_tmp_path / "ref", **KW)
    with monkeypatch.context() as m:
        _signal_during(m, "sdm_dolfinx.io.xdmf_writer.XDMFWriter.write")
        with pytest.raises(Interrupted, match="after step 0"):
            simulate(membrane.problem(N=6), out=out, handle_signals=True, **KW)
    assert read_json(out / "run.json")["status"] == "interrupted"
    simulate(membrane.problem(N=6), out=out, restart=True, **KW)
    if COMM.rank == 0 and COMM.size == 1:
        assert_same_run(mpi_tmp_path / "ref", out)


def test_undo_log_ignores_a_torn_entry(tmp_path):
    """The undo log reader drops a torn last entry (a kill while appending it: the write it
    protects never happened)."""
    from sdm_dolfinx.io import journal
    f = tmp_path / "x.h5"
    f.write_bytes(b"A" * 100)
    jf = journal.JournaledFile(f, committed=100, token="t" * 32)
    jf.reset_log("t" * 32, 100)
    jf._save(10, b"A" * 5)
    jf.close()
    log = journal.undo_path(f)
    log.write_bytes(log.read_bytes() + journal._ENTRY.pack(50, 8) + b"AAA")       # torn
    token, size, entries = journal.read_log(f)
    assert (token, size, entries) == ("t" * 32, 100, [(10, b"A" * 5)])
    f.write_bytes(b"B" * 120)
    assert journal.rollback(f, "t" * 32, 100) == "ok"
    assert f.read_bytes() == b"B" * 10 + b"A" * 5 + b"B" * 85


def test_a_run_started_between_the_check_and_the_lock_is_not_overwritten(mpi_tmp_path):
    """The folder is checked (plan) before the run locks it (simulate): a run that took the
    folder in between (here: the first plan, run to its end) must not be overwritten by the
    second, which is refused in one line naming the other run."""
    from sdm_dolfinx.run import plan
    from sdm_dolfinx.io import RunFolderError, read_info
    out = mpi_tmp_path / "raced"
    first = plan("membrane", {"N": 4}, out=out, dt=0.01, T=0.02)
    second = plan("membrane", {"N": 4}, out=out, dt=0.01, T=0.02)
    done = first.run()
    with pytest.raises(RunFolderError, match="written by another run since this one was checked"):
        second.run()
    saved = read_info(out)
    assert saved["status"] == "finished" and saved["run_id"] == done.info["run_id"]


# ------------------------------------- a full disc at any write of a step: consistent files
def _fail_when_armed(monkeypatch, where):
    """ENOSPC at rank 0's next write into ``where`` ("state.h5", "solution.h5": a byte of its HDF5
    session, after others went through; "solution.xdmf": the XML) once armed (``arm[0] = True``)."""
    import errno
    import os
    from sdm_dolfinx.io import journal, xdmf_writer
    arm = [False]
    full = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    if where == "solution.xdmf":
        orig_text = xdmf_writer.atomic_write_text

        def text(path, *args, **kwargs):
            if arm[0] and str(path).endswith(where):
                raise full
            return orig_text(path, *args, **kwargs)
        monkeypatch.setattr(xdmf_writer, "atomic_write_text", text)
        return arm
    orig, calls = journal._pwrite_all, [0]

    def pwrite(fd, data, off):
        if arm[0] and os.readlink(f"/proc/self/fd/{fd}").endswith(where):
            calls[0] += 1
            if calls[0] > 2:                # a few writes go through first: the session has changed the file
                raise full
        return orig(fd, data, off)
    monkeypatch.setattr(journal, "_pwrite_all", pwrite)
    return arm


@pytest.mark.parametrize("where", ["state.h5", "solution.h5", "solution.xdmf"])
@pytest.mark.parametrize("write_every", [1, 5])
def test_full_disc_leaves_every_file_at_the_last_good_step(mpi_tmp_path, monkeypatch, where, write_every):
    """The disc fills while the fields of step 15 are written (state.h5, solution.h5 or the XDMF
    text): timeseries.csv, state.h5 and solution.xdmf all end at step 14, the last good step
    run.json names, or at the last step written before it (timeseries.csv held step 15 and
    state.h5 did not); the restart is the uninterrupted run."""
    out, ref = mpi_tmp_path / "run", mpi_tmp_path / "ref"
    kw = {**KW, "write_every": write_every}
    simulate(membrane.problem(N=6), out=ref, checkpoint_every=7, **kw)
    with monkeypatch.context() as m:
        arm = _fail_when_armed(m, where)

        def on_step(n, row):
            arm[0] = n == 14 and COMM.rank == 0
        with pytest.raises(RunFileError) as e:
            simulate(membrane.problem(N=6), out=out, checkpoint_every=7, on_step=on_step, **kw)
    assert e.value.no_space and "no space left on device while writing" in str(e.value)
    i = read_json(out / "run.json")
    assert i["status"] == "failed" and i["last_good_step"] == 14
    if COMM.rank == 0:
        import h5py
        from sdm_dolfinx.io.checkpoint import readable_h5
        from sdm_dolfinx.io.xdmf_reader import read_xdmf
        assert readable_h5(out / "solution.h5") and readable_h5(out / "state.h5")
        steps = np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1)[:, 0]
        assert np.array_equal(steps, np.arange(15))
        due = [s for s in range(15) if s % write_every == 0]
        with h5py.File(out / "state.h5") as h5:
            assert list(h5["step"][:]) == due
        assert np.allclose(read_xdmf(out).times, np.array(due) * 2e-3, rtol=0, atol=1e-12)
    simulate(membrane.problem(N=6), out=out, restart=True, checkpoint_every=7, **kw)
    if COMM.rank == 0 and COMM.size == 1:
        assert_same_run(ref, out)
