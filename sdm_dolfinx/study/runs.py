"""Computing the study: run what is missing or out of date, keep what is there.

Every run goes through :func:`sdm_dolfinx.run.simulate` into its own folder of ``runs_dir``.
A folder holding a finished run with the same problem, parameters and options (its
``run.json``) is reused; so is a deterministic failure (the energy blowing up: a result of
the study); a step-solver failure is retried with a factorisation per Newton iteration; an
interrupted long run continues from its checkpoint.
"""
import time
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx.errors import StepError
from sdm_dolfinx.run import RunInputError, grouped, simulate
from sdm_dolfinx.io import CheckpointError, RunFolderError, read_info

COMM = MPI.COMM_WORLD


def read_run_info(folder):
    """``folder/run.json`` as a dict, or None when it is missing or unreadable (not collective)."""
    try:
        return read_info(folder, MPI.COMM_SELF)
    except RunFolderError:
        return None


def run_state(folder, run, ranks):
    """What ``folder`` holds for ``run``: finished, failed (deterministic blow-up: kept),
    retry (a step-solver failure), resumable (interrupted with a checkpoint, same ranks),
    or missing/stale. Not collective (reads on the calling rank)."""
    info = read_run_info(folder)
    if info is None:
        return "missing"
    if not run.matches(info):
        return "stale"
    status = info.get("status")
    if status == "failed" and solver_failure(info) and _linear(info) != "lu":
        return "retry"
    if status in ("finished", "failed"):
        return status
    if status in ("interrupted", "running") and (Path(folder) / "checkpoint.npz").exists() \
            and info.get("ranks") == ranks:
        return "resumable"
    return "stale"


def solver_failure(info):
    """True when a failed run stopped on a step-solver error, not on the energy blowing up."""
    return info.get("status") == "failed" and "not finite" not in info.get("error", "")


def _linear(info):
    return (info.get("run_options") or {}).get("linear", info.get("linear"))


def start(run, folder, comm=COMM, restart=False, progress=False, checkpoint_every=None, linear=None):
    """Compute ``run`` in ``folder`` (collective): a new run replacing what is there, or with
    ``restart`` the continuation of the interrupted run in it; returns the Result.

    Raises:
        StepError: the run failed (its files and run.json say so).
        Interrupted: SIGINT/SIGTERM; a checkpoint was written.
        RunInputError, CheckpointError: a restart refused (or, without ``restart``, bad input).
    """
    extra = {"checkpoint_every": checkpoint_every} if checkpoint_every else {}
    if restart:
        return simulate(out=folder, restart=True, comm=comm, progress=progress, handle_signals=True, **extra)
    if linear is not None:
        extra["linear"] = linear
    return simulate(run.problem, run.params, out=folder, overwrite=True, comm=comm, progress=progress,
                    handle_signals=True, **grouped({**run.options, **extra}))


def compute(run, folder, state, comm=COMM, say=print, progress=False, checkpoint_every=None):
    """Bring ``folder`` up to date for ``run`` from its ``state`` (:func:`run_state`); returns
    "finished" or "failed" (a failed run is kept as a result). Collective.

    Raises:
        Interrupted: the study must stop (SIGINT/SIGTERM).
    """
    kw = dict(comm=comm, progress=progress, checkpoint_every=checkpoint_every)
    try:
        if state == "resumable":
            try:
                start(run, folder, restart=True, **kw)
                return "finished"
            except (RunInputError, CheckpointError):
                pass                     # the checkpoint is unusable: start again
        start(run, folder, linear="lu" if state == "retry" else None, **kw)
        return "finished"
    except StepError:
        if state == "retry":
            return "failed"
    except RunInputError as e:
        raise RuntimeError(f"run {run.name} refused its arguments: {e}") from None
    info = comm.bcast(read_run_info(folder) if comm.rank == 0 else None, root=0) or {}
    if not (solver_failure(info) and _linear(info) != "lu"):
        return "failed"
    say(f"    the step solver failed ({info.get('error', '')[:120]}); again with --linear lu "
        "(a factorisation per Newton iteration)")
    try:
        start(run, folder, linear="lu", **kw)
        return "finished"
    except StepError:
        return "failed"


def ensure_runs(runs, runs_dir, comm=COMM, say=print):
    """Run what is missing or out of date; returns {name: record} (state, wall time, cached).

    Raises:
        sdm_dolfinx.run.Interrupted: a run was interrupted (its checkpoint is kept; running
            the study again continues it).
    """
    runs_dir = Path(runs_dir)
    states = {r.name: comm.bcast(run_state(runs_dir / r.name, r, comm.size) if comm.rank == 0 else None, root=0)
              for r in runs}
    todo = [r for r in runs if states[r.name] not in ("finished", "failed")]
    predicted = sum(r.estimate() for r in todo)
    say(f"study: {len(runs)} runs, {len(runs) - len(todo)} up to date in {runs_dir}, {len(todo)} to compute; "
        f"estimated {duration(predicted)} (serial, from the run times of a 2-core machine)")
    records, spent, spent_pred = {}, 0.0, 0.0
    for i, r in enumerate(runs, 1):
        st = states[r.name]
        if st in ("finished", "failed"):
            records[r.name] = {"state": st, "cached": True}
            continue
        est = r.estimate()
        ratio = spent / spent_pred if spent_pred > 0 else 1.0
        remaining = ratio * sum(x.estimate() for x in todo[todo.index(r):])
        long_run = est > 60          # progress lines and checkpoints only for the long runs
        say(f"[{i}/{len(runs)}] {r.name}: {r.steps} steps, dim W = {r.dim}; est. {duration(est * ratio)} "
            f"(study remaining ~{duration(remaining)})" + (" [resuming from checkpoint]" if st == "resumable" else ""))
        t0 = time.perf_counter()
        state = compute(r, runs_dir / r.name, st, comm, say, progress=long_run,
                        checkpoint_every=max(1, r.steps // 20) if long_run else None)
        wall = time.perf_counter() - t0
        spent += wall
        spent_pred += est
        records[r.name] = {"state": state, "cached": False, "wall": wall}
        say(f"    {state} in {duration(wall)}" + (" (kept as a result: see its run.json)" if state == "failed" else ""))
    return records


def duration(seconds):
    """A duration for people: seconds, minutes or hours."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"
