"""One run of the method comparison: a method on a problem at one (h, dt), in its own folder.

A run's folder holds what :func:`~sdm_dolfinx.run.simulate` writes (``run.json``,
``timeseries.csv``, ``state.h5``), ``fields.csv`` (the field errors measured during the run,
:class:`~sdm_dolfinx.post.metrics.FieldErrors`) and ``metrics.json``, written last: a
folder with ``metrics.json`` is done (finished, failed or refused) and a rerun skips it; a run that
raised an unexpected exception (status ``error``: a bug, not a property of the method) is run again.
"""
import json
import math
import shutil
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx import io as sdm_io
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.post import metrics as cm
from sdm_dolfinx.problems import ProblemInputError, get as get_problem
from sdm_dolfinx.run import Interrupted, RunInputError, grouped, num_steps, plan, simulate
from sdm_dolfinx.run.boundary_sink import BoundaryGapWarning
from sdm_dolfinx.run.linear_range import LinearRangeWarning
from sdm_dolfinx.run import SolverSetupError

COMM = MPI.COMM_WORLD
#: the file that marks a run of the comparison done
METRICS_FILE = "metrics.json"
#: states stored in state.h5 per run (the reference problems' field errors are measured at them)
SAMPLES = 10


def fmt(x):
    """A grid value in a folder name: ``0.025`` -> ``0.025``, ``1/3`` -> ``0.333333``."""
    return f"{x:.6g}"


@dataclass
class Job:
    """One method x (h, dt) of the grid."""
    method: object
    h: float
    dt: float
    T: float
    params: dict
    folder: Path

    @property
    def key(self):
        return (self.method.name, fmt(self.h), fmt(self.dt))

    @property
    def steps(self):
        return num_steps(self.T, self.dt)

    @property
    def write_every(self):
        """Every (steps / SAMPLES)-th state in state.h5 (each run stores the same SAMPLES times when
        steps is a multiple of SAMPLES)."""
        return max(1, self.steps // SAMPLES)

    def label(self):
        return f"{self.method.name} h={fmt(self.h)} dt={fmt(self.dt)}"


def read_metrics(folder):
    """A finished job's ``metrics.json`` (None when there is none or it is unreadable)."""
    try:
        return json.loads((Path(folder) / METRICS_FILE).read_text())
    except (OSError, ValueError):
        return None


def _write_metrics(job, record, comm):
    if comm.rank == 0:
        job.folder.mkdir(parents=True, exist_ok=True)
        atomic_write_text(job.folder / METRICS_FILE, json_text(record))
    comm.Barrier()


def _base_record(job, problem_name):
    return {"method": job.method.name, "problem": problem_name, "h": job.h, "dt": job.dt, "T": job.T,
            "params": job.params, "options": {k: v for k, v in job.method.options.items()},
            "class": job.method.cls, "version": compat.package_version(),
            "problem_file_sha256": get_problem(problem_name).source_sha256}


#: what defines a run of the grid: a stored run differing in any of these is run again
RESUME_KEY = ("method", "problem", "h", "dt", "T", "params", "options", "class", "against", "version",
              "problem_file_sha256")


def stale_because(done, record, folder):
    """What makes the stored run in ``folder`` (its metrics.json ``done``) another run than ``record``
    asks for: the names of :data:`RESUME_KEY` that differ, and the run.json entries (T, the problem's
    parameters, the run options) that differ; empty when it is the same run."""
    want = json.loads(json_text(record))            # as stored: tuples become lists
    why = [k for k in RESUME_KEY if done.get(k) != want.get(k)]
    info = _read_json(Path(folder) / "run.json")
    if info is not None and done.get("status") == "finished":
        if info.get("T") is not None and not math.isclose(info["T"], record["T"], rel_tol=1e-12):
            why.append("T in run.json")
        args = info.get("problem", {}).get("args")
        if args is not None and any(args.get(k) != v for k, v in want["params"].items()):
            why.append("parameters in run.json")
        stored = info.get("run_options", {})
        if any(stored.get(k) != v for k, v in want["options"].items()):
            why.append("options in run.json")
    return list(dict.fromkeys(why))


def _read_json(path):
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def _one_line(e):
    text = next((ln.strip() for ln in str(e).splitlines() if ln.strip()), type(e).__name__)
    return text


def run_job(job, problem_name, problem, truth_of, comm=COMM, exact=None, against="exact solution"):
    """Run ``job`` (unless its folder says it is done) and write its ``metrics.json``; returns the record.

    Args:
        problem_name: the registered problem's name (the run options are checked by
            :func:`sdm_dolfinx.run.plan`, as the command line's are).
        problem: the built :class:`~sdm_dolfinx.problems.Problem` of ``job.params``.
        truth_of: ``truth_of(job, result) -> (truth dict, field rows or None)`` for
            :func:`~sdm_dolfinx.post.metrics.series_metrics` (exact or reference).
        exact: the ExactSolution measured during the run (None: the gap only).
        against: what the metrics compare with (recorded; a finished run measured against something
            else, e.g. another reference run, is run again).
    A folder whose metrics.json describes another run (:func:`stale_because`: another T, dt, h,
    parameter, method option, reference or package version) is run again, never reused.

    Raises:
        Interrupted: a signal stopped the run (the folder has no metrics: a rerun starts it again).
    """
    record = {**_base_record(job, problem_name), "against": against}
    done = comm.bcast(read_metrics(job.folder) if comm.rank == 0 else None, root=0)
    stale = comm.bcast(stale_because(done, record, job.folder) if comm.rank == 0 and done is not None else [],
                       root=0)
    if done is not None and done.get("status") != "error" and not stale:
        return {**done, "cached": True}
    if stale and done.get("status") != "error":
        record["ran_again_because"] = stale          # said in the progress line
    reason = job.method.refusal(problem.mesh.geometry.dim)
    if reason is None:
        reason = _check_options(job, problem_name, comm)
    if reason is not None:
        record.update(status="refused", reason=reason)
        _write_metrics(job, record, comm)
        return record
    if comm.rank == 0 and job.folder.exists():
        shutil.rmtree(job.folder)         # an interrupted attempt: start it again
    comm.Barrier()
    observer = cm.FieldErrors(exact)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():         # the penetration is a metric: no warning line per run; the
            warnings.simplefilter("ignore", BoundaryGapWarning)     # linear range is the problem's, for each method
            warnings.simplefilter("ignore", LinearRangeWarning)
            result = simulate(problem, out=job.folder, observe=observer, dt=job.dt, T=job.T,
                              write_every=job.write_every, **_simulate_options(job))
    except (DiscretisationError, ValueError, ProblemInputError, SolverSetupError) as e:
        record.update(status="refused", reason=_one_line(e))
        _write_metrics(job, record, comm)
        return record
    except Interrupted:
        raise
    except RuntimeError as e:           # StepError (a blow-up, a failed step): its series up to there
        record.update(status="failed", reason=_one_line(e), wall_time=time.perf_counter() - t0)
        record.update(_failed_metrics(job, comm))
        _write_metrics(job, record, comm)
        return record
    except Exception as e:              # a bug, not a property of the method: recorded, and rerun next time
        record.update(status="error", reason=f"{type(e).__name__}: {_one_line(e)}")
        _write_metrics(job, record, comm)
        return record
    truth, rows = truth_of(job, result, observer)
    info = {**result.info, "observe_time": observer.seconds}
    metrics = cm.series_metrics(result.timeseries, info, truth, rows) if truth is not None else {}
    record.update(status="finished", dofs=int(result.info.get("dim_W", 0)), steps=int(result.info["steps"]),
                  wall_time=float(result.info.get("wall_time", math.nan)), **metrics)
    if comm.rank == 0 and exact is not None:
        atomic_write_text(job.folder / "fields.csv", observer.csv_text())
    _write_metrics(job, record, comm)
    return record


def _simulate_options(job):
    """The method's run options as simulate's keywords (a scheme's or treatment's in its group)."""
    return grouped(job.method.run_options())


def _check_options(job, problem_name, comm):
    """The run options as the command line checks them: None if accepted, else the one line."""
    try:
        plan(problem_name, job.params, comm=comm, dt=job.dt, T=job.T, write_every=job.write_every,
             **_simulate_options(job))
    except RunInputError as e:
        return _one_line(e)
    return None


def _failed_metrics(job, comm):
    """What a failed run's series still says: when it failed and its energy error up to then (not a
    metric: the ranking counts a failed run's metrics as infinite)."""
    try:
        ts = sdm_io.read_timeseries(job.folder, comm)
    except Exception:               # no series at all: the run failed at its first step
        return {"failed_at_t": 0.0}
    E = np.asarray(ts.get("energy", []), dtype=float)
    return {"failed_at_t": float(ts["t"][-1]) if len(E) else 0.0,
            "energy_error_before_failure": cm.energy_errors(E)[1]}
