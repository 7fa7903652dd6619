"""The method comparison: methods x h x dt on one problem, against its exact solution
or, for a problem without one, against the finest well-posed run; CSV/JSON of the metrics, figures
and a ranking.

    from sdm_dolfinx.paper import compare
    cmp = compare.make_comparison("rod1d", "all", quick=True, out="output/compare-rod1d")
    records = compare.run_comparison(cmp)          # resumable: finished runs are kept
    compare.write_outputs(cmp, records)            # compare.csv, compare.json, figures, ranking.md/html

Each run lives in ``out/runs/METHOD/h<h>_dt<dt>/`` (the reference of a problem without an exact
solution in ``out/runs/reference/``) with its ``metrics.json``
(:mod:`.compare_grid`); the metrics are :mod:`sdm_dolfinx.post.metrics`'s.
"""
import csv
import io
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import problems
from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.compare import figures as compare_figures
from sdm_dolfinx.compare import reference as compare_reference
from sdm_dolfinx.compare import table as compare_table
from sdm_dolfinx.compare.grid import METRICS_FILE, Job, fmt, run_job
from sdm_dolfinx.compare.catalogue import METHODS, select
from sdm_dolfinx.study.text import jsonable
from sdm_dolfinx.post import metrics as cm

COMM = MPI.COMM_WORLD
#: the grids of ``--quick`` (about a minute on one core): h values, dt = dt_ratio x h, T
QUICK = {"rod1d": {"h": [1 / 10, 1 / 20, 1 / 40], "dt_ratio": 0.5, "T": 3.0},
         "bar": {"h": [1 / 10, 1 / 20, 1 / 40], "dt_ratio": 0.5, "T": None},
         "membrane": {"h": [1 / 4, 1 / 8], "dt_ratio": 0.02, "T": 0.3},
         # the block dropped unstressed onto the floor (an impact; its static start is the equilibrium of
         # the vertex constraint, which the constraint at every node refuses)
         "block": {"h": [4.0, 2.0], "dt_ratio": 5e-5, "T": None, "params": {"start": "rest"}},
         "disc": {"h": [4.0, 2.0], "dt_ratio": 5e-5, "T": None}}
#: the method whose refined run is the reference of a problem without an exact solution
DEFAULT_REFERENCE = "sdm-p2p1"
#: the reference run refines the finest grid point's h and dt by this factor
REFERENCE_REFINEMENT = 2
#: the columns of compare.csv before the metrics
ID_COLUMNS = ("problem", "method", "class", "h", "dt", "T", "status", "dofs", "steps", "wall_time", "reason")


@dataclass
class Comparison:
    """One comparison: a problem, its methods and the (h, dt) grid."""
    problem: str
    methods: list
    grid: list                  # [(h, dt)]
    T: float
    out: Path
    params: dict = field(default_factory=dict)
    reference: str = DEFAULT_REFERENCE
    quick: bool = False
    runs_dir: Optional[Path] = None     # the runs' folders (default out/runs)

    def __post_init__(self):
        self.out = Path(self.out)
        self.runs_dir = Path(self.runs_dir) if self.runs_dir is not None else self.out / "runs"

    def folder(self, method, h, dt):
        """The folder of one run."""
        return self.runs_dir / method / f"h{fmt(h)}_dt{fmt(dt)}"

    @property
    def spec(self):
        return problems.get(self.problem)

    @property
    def exact(self):
        """The problem's exact solution factory (``ProblemSpec.exact``) or None."""
        return getattr(self.spec, "exact", None)

    def jobs(self):
        """Every method x (h, dt), coarse first."""
        out = []
        for h, dt in sorted(self.grid, key=lambda p: (-p[0], -p[1])):
            for m in self.methods:
                out.append(Job(m, h, dt, self.T, mesh_params(self.spec, h, self.params), self.folder(m.name, h, dt)))
        return out

    def reference_job(self):
        """The reference run (problems without an exact solution): the reference method at the
        finest h and dt divided by :data:`REFERENCE_REFINEMENT`."""
        h = min(h for h, _ in self.grid) / REFERENCE_REFINEMENT
        dt = min(dt for _, dt in self.grid) / REFERENCE_REFINEMENT
        return Job(METHODS[self.reference], h, dt, self.T, mesh_params(self.spec, h, self.params),
                   self.runs_dir / "reference" / f"{self.reference}_h{fmt(h)}_dt{fmt(dt)}")


def mesh_params(spec, h, given=None):
    """The problem's parameters for mesh size ``h``: its ``h`` parameter; or cells along and across,
    ``nx``, ``ny`` (any case: ``Nx``, ``Ny``) = width / h, height / h (``width``, ``length``, ``L`` and
    ``height``, ``H``, else 1); or cells along one length, ``N``, ``NX`` or ``n`` = length / h; ``given``
    for the others."""
    given = dict(given or {})
    names = {p.name.lower(): p.name for p in spec.params}

    def value(*options, default=1.0):
        for n in options:
            if n in names.values():
                return float(given.get(n, spec.param(n).default))
        return default

    def cells(size):
        return max(1, int(round(size / h)))
    if "h" in names.values():
        return {**given, "h": h}
    if "nx" in names and "ny" in names:
        return {**given, names["nx"]: cells(value("width", "length", "L")), names["ny"]: cells(value("height", "H"))}
    for n in ("N", "NX", "n"):
        if n in names.values():
            return {**given, n: cells(value("length", "L", "width"))}
    raise ValueError(f"problem {spec.name!r} has no mesh-size parameter the comparison knows (h; nx and ny; N or n)")


def make_comparison(problem, methods="all", hs=None, dts=None, dt_ratio=None, T=None, out=None, quick=False,
                    params=None, reference=DEFAULT_REFERENCE, runs_dir=None):
    """A checked :class:`Comparison` (ValueError, one line, for bad input).

    The grid is every h x every dt of ``dts``, or dt = ``dt_ratio`` x h for each h (a path along
    which h and dt are refined together); ``quick`` takes the problem's :data:`QUICK` grid for what
    is not given. T defaults to the problem's declared T. ``problem``: a registered name or the path of
    a problem file (``.py``: loaded and registered, compared by its name from then on).
    """
    if str(problem).endswith(".py"):
        try:
            problem = problems.load_file(problem).name
        except problems.ProblemInputError as e:
            raise ValueError(str(e)) from None
    spec = problems.get(problem) if problem in problems.names() else None
    if spec is None:
        raise ValueError(f"unknown problem {problem!r}; choose one of {', '.join(problems.names())}")
    q = QUICK.get(problem, {}) if quick else {}
    if quick and not q and (hs is None or (dts is None and dt_ratio is None)):
        raise ValueError(f"no quick grid for problem {problem!r}: give --h and --dt (or --dt-ratio)")
    hs = list(hs or q.get("h") or [])
    if dts is None and dt_ratio is None:
        dt_ratio = q.get("dt_ratio")
    T = float(T or q.get("T") or spec.defaults.get("T") or 1.0)
    if not hs or (dts is None and dt_ratio is None):
        raise ValueError("give the mesh sizes --h and the time steps --dt (or --dt-ratio), or --quick")
    if any(not (x > 0 and math.isfinite(x)) for x in hs + list(dts or []) + [T, dt_ratio or 1.0]):
        raise ValueError("h, dt, --dt-ratio and T must be positive finite numbers")
    grid = [(h, dt) for h in hs for dt in dts] if dts else [(h, dt_ratio * h) for h in hs]
    for _, dt in grid:
        if abs(T / dt - round(T / dt)) > 1e-9 * (T / dt) or round(T / dt) < 1:
            raise ValueError(f"T = {T:g} is not a whole number of steps of dt = {dt:g}")
    if reference not in METHODS:
        raise ValueError(f"unknown reference method {reference!r}; choose among {', '.join(METHODS)}")
    mesh_params(spec, hs[0], params)           # a problem without a mesh-size parameter is refused here
    out = Path(out or f"output/compare-{problem}{'-quick' if quick else ''}")
    params = {**q.get("params", {}), **dict(params or {})}
    return Comparison(problem, select(methods), grid, T, out, params, reference, quick, runs_dir)


# ----------------------------------------------------------------------------- running the grid
class _Truths:
    """The exact (or reference) values each job is measured against, per mesh (built once)."""

    def __init__(self, cmp, comm, say):
        self.cmp, self.comm, self.say, self.problems = cmp, comm, say, {}
        self.ref = None
        self.against = "exact solution"

    def problem(self, job):
        key = tuple(sorted(job.params.items()))
        if key not in self.problems:
            self.problems[key] = self.cmp.spec.problem(self.comm, **job.params)
        return self.problems[key]

    def exact(self, job):
        return self.cmp.exact(self.problem(job)) if self.cmp.exact is not None else None

    def truth_of(self, job, result, observer):
        """(truth, field rows) for :func:`~sdm_dolfinx.post.metrics.series_metrics`."""
        if self.cmp.exact is not None:
            truth = cm.exact_truth(self.exact(job), self.problem(job).probe, job.T)
            truth["u_scale"] = observer.displacement_scale()
            return truth, observer.table()
        rows = compare_reference.field_rows(job.folder, self.ref.folder, self.comm)
        rows["gap"] = observer.table()["gap"]
        truth = cm.reference_truth(self.ref_ts)
        truth["u_scale"] = rows.pop("u_scale")
        return truth, rows

    def reference(self):
        """Run the reference (problems without an exact solution) unless done; keep its series."""
        job = self.cmp.reference_job()
        self.say(f"reference: {job.label()} ({job.folder})")
        rec = run_job(job, self.cmp.problem, self.problem(job), lambda j, r, o: (None, None), self.comm)
        if rec.get("status") != "finished":
            raise RuntimeError(f"the reference run {job.label()} did not finish: "
                               f"{rec.get('reason', rec.get('status'))}")
        self.ref, self.ref_ts = job, compare_reference.read_series(job.folder)
        self.against = f"reference run {job.folder.name}"


def run_comparison(cmp, comm=COMM, say=None):
    """Run every job not done yet (collective); returns the records (one per job, in grid order)."""
    say = say or ((lambda s: print(s, flush=True)) if comm.rank == 0 else (lambda s: None))
    truths = _Truths(cmp, comm, say)
    if cmp.exact is None:
        truths.reference()
    jobs = cmp.jobs()
    records, t_start = [], time.perf_counter()
    for k, job in enumerate(jobs):
        t0 = time.perf_counter()
        rec = run_job(job, cmp.problem, truths.problem(job), truths.truth_of, comm, truths.exact(job),
                      truths.against)
        records.append(rec)
        if not rec.get("cached"):       # a progress line per run computed now; the others are counted below
            say(f"[{k + 1}/{len(jobs)}] {job.label()}: {_progress(rec)} ({time.perf_counter() - t0:.1f} s)"
                f"  [{time.perf_counter() - t_start:.0f} s]")
    done = sum(1 for r in records if r.get("cached"))
    if done:
        say(f"{done} of {len(jobs)} runs done before (read from their folders' {METRICS_FILE})")
    return records


def _progress(rec):
    again = (f" (ran again: the stored run's {', '.join(rec['ran_again_because'])} differed)"
             if rec.get("ran_again_because") else "")
    if rec.get("status") != "finished":
        return f"{rec.get('status')}: {rec.get('reason', '')}{again}"
    stress = ("n/d" if "stress_contact_L2t" in (rec.get("undefined") or {})
              else f"{rec['stress_contact_L2t']:.2e}")
    return (f"energy error {rec['energy_error_max']:.2e}, u Linf(L2) {rec.get('u_LinfL2', math.nan):.2e}, "
            f"stress L2(t) {stress}, penetration {rec['penetration_max']:.1e}{again}")


# ----------------------------------------------------------------------------- outputs
def csv_text(records):
    """compare.csv: one row per run, identifiers then every metric."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(ID_COLUMNS) + list(cm.METRICS))
    for r in records:
        w.writerow([r.get(c, "") for c in ID_COLUMNS] + [_num(r.get(k)) for k in cm.METRICS])
    return buf.getvalue()


def _num(v):
    return "" if v is None else f"{float(v):.6g}"


def summary(cmp, records):
    """What compare.json holds: the grid, the records, the fitted rates and the ranking."""
    fitted = compare_table.rates(records)
    return {"problem": cmp.problem, "T": cmp.T, "grid": cmp.grid, "quick": cmp.quick,
            "against": "exact solution" if cmp.exact is not None else f"reference run ({cmp.reference}, h and dt / "
                                                                     f"{REFERENCE_REFINEMENT})",
            "methods": {m.name: {"description": m.description, "follows": m.follows, "class": m.cls,
                                 "options": m.options} for m in cmp.methods},
            "metrics": cm.METRICS, "records": records, "rates": fitted,
            "ranking": compare_table.ranking(records)}


def write_outputs(cmp, records, comm=COMM):
    """compare.csv, compare.json, ranking.md, ranking.html and the figures in ``cmp.out`` (rank 0
    writes; collective). Returns compare.json's content."""
    data = None
    if comm.rank == 0:
        data = jsonable(summary(cmp, records))
        out = cmp.out
        out.mkdir(parents=True, exist_ok=True)
        title = f"Method comparison: {cmp.problem} ({data['against']})"
        atomic_write_text(out / "compare.csv", csv_text(records))
        data["figures"] = compare_figures.all_figures(cmp, records, truth_for_figures(cmp), out)
        atomic_write_text(out / "compare.json", json_text(_finite(data), indent=1))
        atomic_write_text(out / "ranking.md", compare_table.markdown(data["ranking"], data["rates"], title))
        atomic_write_text(out / "ranking.html", compare_table.html_page(data["ranking"], data["rates"], title))
    return comm.bcast(data, root=0)


def truth_for_figures(cmp):
    """The exact (or reference) values at the contact point, on the calling rank alone: the exact
    solution of the coarsest mesh's problem (built on MPI.COMM_SELF), or the reference run's series
    (None when it is missing)."""
    if cmp.exact is not None:
        h = max(h for h, _ in cmp.grid)
        problem = cmp.spec.problem(MPI.COMM_SELF, **mesh_params(cmp.spec, h, cmp.params))
        return cm.exact_truth(cmp.exact(problem), problem.probe, cmp.T)
    try:
        return cm.reference_truth(compare_reference.read_series(cmp.reference_job().folder))
    except Exception:           # no reference series: the figures show the runs alone
        return None


def _finite(d):
    """JSON has no inf or nan: they become the strings "inf" and "nan"."""
    if isinstance(d, dict):
        return {k: _finite(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [_finite(v) for v in d]
    if isinstance(d, float) and not np.isfinite(d):
        return str(d)
    return d
