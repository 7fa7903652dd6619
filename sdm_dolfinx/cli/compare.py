"""``python -m sdm_dolfinx compare``: every method of the comparison on one problem, over a grid of
mesh sizes and time steps, against the exact solution (or the finest well-posed run), with a CSV/JSON
of the metrics, figures and a ranking (:mod:`sdm_dolfinx.compare.comparison`).

    python -m sdm_dolfinx compare --problem rod1d --methods all --h 1/20,1/40,1/80 --dt-ratio 0.5
    python -m sdm_dolfinx compare --problem rod1d --quick
    mpirun -n 2 python -m sdm_dolfinx compare --problem membrane --methods sdm-p2p1,standard-newmark --quick

Exit status: 0 done, 1 some run raised an unexpected error (listed; rerunning retries it), 2 bad
input (one line), 130 interrupted (rerunning the same command continues: finished runs are kept).
"""
import argparse
import sys
import time
from fractions import Fraction
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx import problems
from sdm_dolfinx.cli.common import Parser, UsageError, folder_path, parse_or_help, report_usage_error
from sdm_dolfinx.compare import comparison as compare
from sdm_dolfinx.compare.catalogue import METHODS, describe
from sdm_dolfinx.run import Interrupted

PROG = "python -m sdm_dolfinx compare"


def number_list(text):
    """argparse type: comma-separated positive numbers, each a decimal or a fraction (``1/20``)."""
    out = []
    for item in str(text).split(","):
        item = item.strip()
        try:
            v = float(Fraction(item)) if "/" in item else float(item)
        except (ValueError, ZeroDivisionError):
            raise argparse.ArgumentTypeError(f"not a number: {item!r}") from None
        if not 0 < v < float("inf"):
            raise argparse.ArgumentTypeError(f"must be positive finite numbers (got {item})")
        out.append(v)
    return out


def positive_number(text):
    """argparse type: one positive number (a fraction allowed)."""
    values = number_list(text)
    if len(values) != 1:
        raise argparse.ArgumentTypeError(f"one number, not a list (got {text!r})")
    return values[0]


def param(text):
    """argparse type: ``NAME=VALUE`` (an integer, a number or a word)."""
    name, sep, value = str(text).partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE (got {text!r})")
    for kind in (int, float):
        try:
            return name.strip(), kind(value)
        except ValueError:
            pass
    return name.strip(), value


def build_parser():
    p = Parser(prog=PROG, description="Compare dynamic-contact methods on one problem over a grid of mesh sizes "
               "and time steps: metrics against the exact solution (or the finest well-posed run), figures and "
               "a ranking. Resumable: a rerun skips the finished runs.")
    p.add_argument("--problem", default=None, help=f"a registered problem ({', '.join(problems.names())})")
    p.add_argument("--problem-file", type=Path, default=None, metavar="FILE",
                   help="a problem of your own: a Python file defining PROBLEM = ProblemSpec(...) with a mesh-size "
                        "parameter (h; nx and ny; N or n); without an exact solution the reference is the finest "
                        "well-posed run (--reference)")
    p.add_argument("--methods", default="all", help="'all' or a comma-separated list (see --list)")
    p.add_argument("--h", type=number_list, default=None, help="mesh sizes, comma-separated (1/20 allowed)")
    p.add_argument("--dt", type=number_list, default=None, help="time steps, comma-separated: the grid is every h "
                   "x every dt")
    p.add_argument("--dt-ratio", type=positive_number, default=None, help="instead of --dt: dt = ratio x h for "
                   "each h (h and dt refined together)")
    p.add_argument("--T", type=positive_number, default=None, help="final time (default: the problem's)")
    p.add_argument("--param", type=param, action="append", default=[], metavar="NAME=VALUE",
                   help="a problem parameter other than the mesh size (repeatable)")
    p.add_argument("--reference", default=compare.DEFAULT_REFERENCE, choices=sorted(METHODS),
                   metavar="METHOD", help="the method whose refined run is the reference of a problem without an "
                   f"exact solution (default {compare.DEFAULT_REFERENCE})")
    p.add_argument("--quick", action="store_true", help="a minute's grid (the problem's coarse h, dt = h/2)")
    p.add_argument("--out", type=folder_path, default=None, help="output folder (default output/compare-PROBLEM)")
    p.add_argument("--list", action="store_true", help="list the methods and exit")
    return p


def _comparison(args):
    """The checked comparison (UsageError, one line, otherwise)."""
    if args.problem is None and args.problem_file is None:
        raise UsageError("--problem is required (or --problem-file, or --list)")
    if args.problem is not None and args.problem_file is not None:
        raise UsageError("--problem and --problem-file: choose one")
    if args.dt is not None and args.dt_ratio is not None:
        raise UsageError("give --dt or --dt-ratio, not both")
    params = dict(args.param)
    try:
        cmp = compare.make_comparison(args.problem or str(args.problem_file), args.methods, args.h, args.dt,
                                      args.dt_ratio, args.T, args.out, args.quick, params, args.reference)
        cmp.spec.values(compare.mesh_params(cmp.spec, cmp.grid[0][0], params), cli=False)
    except (ValueError, KeyError) as e:
        raise UsageError(str(e).strip("'\"")) from None
    _check_out(cmp.out)
    return cmp


def _check_out(out):
    probe = Path(out)
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise UsageError(f"cannot write to {out}: {probe} is not a folder")
    import os
    if not os.access(probe, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write to {out} ({probe} is not writable)")


def main(argv=None):
    """``python -m sdm_dolfinx compare``: returns the exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    comm = MPI.COMM_WORLD
    say = (lambda s: print(s, flush=True)) if comm.rank == 0 else (lambda s: None)
    try:
        args = parse_or_help(build_parser(), argv, comm)
        if args is None:
            return 0
        if args.list:
            for line in describe():
                say(line)
            return 0
        cmp = _comparison(args)
    except UsageError as e:
        return report_usage_error(PROG, e, comm)
    jobs = len(cmp.jobs())
    say(f"{PROG}: {cmp.problem}, {len(cmp.methods)} methods x {len(cmp.grid)} (h, dt) = {jobs} runs, T = {cmp.T:g}"
        f" -> {cmp.out}")
    t0 = time.perf_counter()
    try:
        records = compare.run_comparison(cmp, comm, say)
    except (Interrupted, KeyboardInterrupt) as e:
        say(f"{PROG}: interrupted; rerun the same command to continue (finished runs are kept)")
        return 128 + int(getattr(e, "signum", 2))
    data = compare.write_outputs(cmp, records, comm)
    errors = [r for r in records if r.get("status") == "error"]
    if comm.rank == 0:
        top = data["ranking"]["order"][:3]
        say(f"wrote {cmp.out}/compare.csv, compare.json, ranking.md, ranking.html and "
            f"{sum(len(v) for v in data['figures'].values())} figures in {time.perf_counter() - t0:.0f} s; "
            f"best mean rank: {', '.join(top)}")
        for r in errors:
            print(f"{PROG}: error: {r['method']} h={r['h']:g} dt={r['dt']:g}: {r['reason']} (run again next time)",
                  file=sys.stderr, flush=True)
    return 1 if errors else 0
