"""Real signals at random moments: SIGKILL (item 1 of "Reliability II") and SIGINT (item 6).

A run killed at any moment -- while it steps, writes its fields, writes a checkpoint, or
while a restart restores its files -- always restarts, and its files end identical, bit for
bit, to an uninterrupted run's. A SIGINT at any moment leaves a folder that is either absent
(nothing written yet), interrupted with a checkpoint that restarts, or finished.
"""
import random
import signal
import time

from mpi4py import MPI

import pytest

from test_faults_common import assert_same_run, error_lines, info, rows, run, start

COMM = MPI.COMM_WORLD
serial_only = pytest.mark.skipif(COMM.size > 1, reason="signals separate serial processes")

#: a small run: 600 steps (contact from t ~ 0.25), fields and state.h5 at every step
ARGS = ["membrane", "--N", "8", "--T", "1.2", "--write-every", "1", "--checkpoint-every", "7", "--quiet"]
STEPS = 1200


def _csv_inode(folder):
    try:
        return (folder / "timeseries.csv").stat().st_ino
    except FileNotFoundError:
        return None


def _kill_at(p, folder, rng, mode, inode=None):
    """SIGKILL ``p`` at a random moment: ``time``: after a random delay (start-up, the
    restart's restore, or steps); ``step``: once the restart has cut its time series back to
    the checkpoint (``inode``: the series' inode before; it is rewritten then) and the series
    has grown by a random 1 to 40 rows, plus up to 4 ms (inside a step's solve or writes).
    Returns what happened (None: the run ended first)."""
    t0 = time.monotonic()
    if mode == "time":
        deadline = t0 + rng.uniform(0.05, 1.0)
        while p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.002)
        what = f"after {time.monotonic() - t0:.2f} s"
    else:
        while p.poll() is None and inode is not None and _csv_inode(folder) == inode and time.monotonic() - t0 < 120:
            time.sleep(0.002)
        target = min(rows(folder) + rng.randint(1, 40), STEPS - 5)
        while p.poll() is None and rows(folder) < target and time.monotonic() - t0 < 120:
            time.sleep(0.002)
        time.sleep(rng.uniform(0.0, 0.004))
        what = f"near step {target}"
    if p.poll() is not None:
        return None
    p.send_signal(signal.SIGKILL)
    p.wait(timeout=60)
    return what


@serial_only
@pytest.mark.slow       # 16 s on a quiet 2-core machine, 36 s on a loaded one
def test_sigkill_at_random_moments_always_restarts_identically(tmp_path):
    """Twelve SIGKILLs of one run (the first after its first checkpoint, the others of its
    restarts): every restart succeeds, and the finished files equal an uninterrupted run's
    bit for bit (timeseries.csv, the XDMF XML and every field at every time, state.h5)."""
    ref, cut = tmp_path / "ref", tmp_path / "cut"
    rng = random.Random(20240611)
    p = start(ARGS + ["--out", cut])
    while p.poll() is None and not (cut / "checkpoint.npz").exists():
        time.sleep(0.002)
    kills, inode = [], None
    for i in range(12):
        what = _kill_at(p, cut, rng, "time" if i % 3 == 2 else "step", inode)
        assert what is not None, f"the run ended before kill {i + 1}: {p.stderr.read()}"
        kills.append(what)
        assert info(cut)["status"] == "running"          # nothing had a chance to say otherwise
        inode = _csv_inode(cut)
        p = start(["membrane", "--restart", cut, "--quiet"])
    _, err = p.communicate(timeout=300)
    assert p.returncode == 0, f"after kills {kills}: {err}"
    r = run(ARGS + ["--out", ref])
    assert r.returncode == 0, r.stderr
    assert_same_run(ref, cut)


@serial_only
@pytest.mark.slow
def test_sigint_at_random_moments_leaves_a_restartable_or_empty_folder(tmp_path):
    """SIGINT at random moments (0.2 s to 2 s after the start: imports, set-up, the first
    files, the steps) and at events (as soon as run.json appears, at the first row, at a
    random row): the folder is never left "running" without a checkpoint. Either nothing was
    written, or the run says "interrupted" (one line, exit 130) and its restart finishes
    it, or it had finished."""
    rng = random.Random(7)
    moments = [("time", rng.uniform(0.2, 2.0)) for _ in range(3)] + [("json", 0), ("rows", 1),
                                                                     ("rows", rng.randint(2, 900))]
    seen = set()
    for k, (kind, when) in enumerate(moments):
        out = tmp_path / f"run{k}"
        p = start(["membrane", "--N", "8", "--T", "1", "--write-every", "5", "--out", out])
        t0 = time.monotonic()
        while p.poll() is None and time.monotonic() - t0 < 60:
            if (kind == "time" and time.monotonic() - t0 >= when or kind == "json" and (out / "run.json").exists()
                    or kind == "rows" and rows(out) >= when):
                break
            time.sleep(0.001)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=120)
        if not (out / "run.json").exists():            # stopped before the run wrote anything
            assert not out.exists() or not any(f.name != ".lock" for f in out.iterdir()), err
            seen.add("nothing")
            continue
        status = info(out)["status"]
        seen.add(status)
        assert status in ("interrupted", "finished"), (kind, when, status, err)
        if status == "finished":
            # the signal came after the run's handlers were restored (the run had ended and its
            # files were complete): Python's own SIGINT handling may end the process then
            assert p.returncode in (0, 130, -signal.SIGINT), err
            continue
        assert p.returncode == 128 + signal.SIGINT and len(error_lines(err)) == 1, err
        assert "Traceback" not in err and (out / "checkpoint.npz").exists()
        r = run(["membrane", "--restart", out, "--quiet"])
        assert r.returncode == 0 and info(out)["status"] == "finished", r.stderr
    assert "interrupted" in seen
