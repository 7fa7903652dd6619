"""``python -m sdm_dolfinx figures``: rerun the paper's studies (only what is missing) and
regenerate its figures, Table 2 and an HTML report (:mod:`sdm_dolfinx.paper`).

Exit status: 0 done, 2 bad input (one line), 128 + signal when a run was interrupted
(rerunning the same command continues it).
"""
import os
import sys
import time
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx import compat
from sdm_dolfinx.cli.common import Parser, UsageError, parse_or_help, report_usage_error
from sdm_dolfinx.report import hertz_entry as hertz_report
from sdm_dolfinx.report.build import make_report
from sdm_dolfinx.study.runs import duration, ensure_runs, run_state
from sdm_dolfinx.report.studies import make_study
from sdm_dolfinx.problems.disc_mesh import LEVELS
from sdm_dolfinx.run import Interrupted

PROG = "python -m sdm_dolfinx figures"


def build_parser():
    p = Parser(prog=PROG, description="Rerun the paper's studies (only what is missing) and regenerate "
               "its figures, Table 2 and an HTML report from the runs' output files.")
    p.add_argument("--quick", action="store_true", help="coarser, shorter study (a few minutes): smoke test")
    p.add_argument("--out", type=Path, default=None,
                   help="report folder (default report/, or output/report-quick with --quick)")
    p.add_argument("--runs", type=Path, default=None,
                   help="folder of the runs (default output/study, or output/study-quick)")
    p.add_argument("--disc-max-level", type=int, default=None, choices=sorted(LEVELS)[1:],
                   help="finest disc level of the convergence study, the reference (default 6, the paper's: "
                        "513k dofs, about 30 min and 5 GB on its own; 3 with --quick)")
    p.add_argument("--dry-run", action="store_true", help="print the plan and the estimated time, run nothing")
    return p


def _folders(args):
    """(report folder, runs folder), each writable (UsageError otherwise)."""
    out = args.out or (Path("output/report-quick") if args.quick else Path("report"))
    runs_dir = args.runs or (Path("output/study-quick") if args.quick else Path("output/study"))
    for p in (out, runs_dir):
        probe = p
        while not probe.exists():
            probe = probe.parent
        if not probe.is_dir() or not os.access(probe, os.W_OK):
            raise UsageError(f"cannot write to {p}")
    return out, runs_dir


def dry_run(runs, runs_dir, comm, say, quick=False):
    """The plan: each run's state and estimated time; nothing is run or written."""
    total = 0.0
    for r in runs:
        st = comm.bcast(run_state(runs_dir / r.name, r, comm.size) if comm.rank == 0 else None, root=0)
        est = 0.0 if st in ("finished", "failed") else r.estimate()
        total += est
        say(f"{r.name:58s} {r.steps:6d} steps  dim W {r.dim:7d}  {st:9s} est. {duration(est)}")
    say(f"{len(runs)} runs; estimated {duration(total)} to compute on the reference machine")
    ball = hertz_report.RUNS[quick]
    stored = sum(1 for lev, dt in ball if comm.bcast(
        hertz_report.read_row(runs_dir / "hertz" / hertz_report.run_name(lev, dt), hertz_report.key_of(lev, dt))
        is not None if comm.rank == 0 else None, root=0))
    plan = " ".join(f"{lev}:{dt:g}" for lev, dt in ball)
    say(f"then the report's own studies: the method comparison, and the ball against Hertz ({len(ball)} "
        f"run{'s' * (len(ball) > 1)}, level:dt {plan}; {stored} stored in {runs_dir / 'hertz'})")
    return 0


def main(argv=None):
    """``python -m sdm_dolfinx figures``: returns the exit status (0 ok, 2 bad input, 128+sig interrupted)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    comm = MPI.COMM_WORLD
    say = (lambda s: print(s, flush=True)) if comm.rank == 0 else (lambda s: None)
    try:
        args = parse_or_help(build_parser(), argv, comm)
        if args is None:
            return 0
        out, runs_dir = _folders(args)
        study = make_study(args.quick, args.disc_max_level)
    except UsageError as e:
        return report_usage_error(PROG, e, comm)
    runs = study.runs()
    if args.dry_run:
        return dry_run(runs, runs_dir, comm, say, args.quick)
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
        runs_dir.mkdir(parents=True, exist_ok=True)
    comm.Barrier()
    say(f"sdm_dolfinx figures: {'quick' if args.quick else 'full'} study -> runs in {runs_dir}, report in {out}")
    t0 = time.perf_counter()
    try:
        records = ensure_runs(runs, runs_dir, comm, say)
    except Interrupted as e:
        say(f"{PROG}: interrupted; rerun the same command to continue (finished runs are kept)")
        return 128 + int(e.signum)
    say("post-processing: H1 errors between non-matching disc meshes, energy checks, figures, report")
    computed = sum(1 for r in records.values() if not r["cached"])
    v = compat.versions()
    meta = {"ranks": comm.size, "wall": time.perf_counter() - t0, "computed": computed,
            "cached": len(records) - computed, "command": " ".join([PROG] + argv),
            "versions": f"dolfinx {v['dolfinx']}, PETSc {v['petsc']}"}
    make_report(study, runs_dir, out, records, comm, say, meta)
    if comm.rank == 0:
        meta["wall"] = time.perf_counter() - t0
        say(f"wrote {out}/index.html, numbers.json and {len(list(out.glob('*.png')))} PNGs in "
            f"{duration(meta['wall'])}")
    return 0
