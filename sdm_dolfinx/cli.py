"""Command line: ``python -m sdm_dolfinx <problem> [options]``.

Every problem module (membrane, ...) provides ``DEFAULTS``, ``add_arguments(parser)``,
``check_arguments(args)`` and ``problem_from_args(args, comm)``; the run options below are
common to all. Bad input: a one-line message on stderr and exit status 2, before anything
is written. A failed step: a one-line message and exit status 1, outputs kept up to the
last good step and ``run.json`` saying ``"status": "failed"``.
"""
import argparse
import json
import math
import os
import sys
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

from . import membrane
from .integrator import SCHEMES, StepError
from .pairs import MASS_TREATMENTS, PAIRS, get_pair
from .simulate import num_steps, simulate
from .vi import LINEAR_STRATEGIES, VI_SOLVERS

PROBLEMS = {"membrane": membrane}
#: commands that are not a run: name -> module with ``main(argv) -> exit status``
SUBCOMMANDS = {}


class UsageError(Exception):
    """Bad input: reported in one line with exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(f"{self.prog}: error: {message}")


def _positive_float(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number (got {text})")
    return v


def add_run_arguments(p, defaults):
    g = p.add_argument_group("discretisation and run")
    g.add_argument("--pair", default=defaults["pair"], choices=list(PAIRS), metavar="PAIR",
                   help=f"(W^h, H^h) pair: {', '.join(PAIRS)} (default {defaults['pair']})")
    g.add_argument("--mass", choices=MASS_TREATMENTS, default=None,
                   help="C treatment: diagonal (P0), lumped or consistent (P1 velocity; consistent solves the "
                        "(U, V) block system), standard (H = W); default: diagonal for P0, lumped for P1")
    g.add_argument("--scheme", default=defaults["scheme"], choices=list(SCHEMES),
                   help=f"time scheme (default {defaults['scheme']})")
    g.add_argument("--dt", type=_positive_float, default=defaults["dt"], help=f"time step (default {defaults['dt']})")
    g.add_argument("--T", type=_positive_float, default=defaults["T"], help=f"final time (default {defaults['T']})")
    g.add_argument("--vi-solver", choices=VI_SOLVERS, default="ssn",
                   help="step solver: ssn = semi-smooth Newton / primal-dual active set (default), or PETSc SNES "
                        "vinewtonrsls / vinewtonssls")
    g.add_argument("--linear", choices=LINEAR_STRATEGIES, default="cg-factor",
                   help="linear solves of the semi-smooth Newton: cg-factor = one factorisation of the step matrix "
                        "per run, Krylov on the inactive set (default); lu = refactor each iteration; amg = CG + "
                        "BoomerAMG")
    o = p.add_argument_group("output")
    o.add_argument("--out", type=Path, default=None, help="output folder (default output/<problem>)")
    o.add_argument("--write-every", type=int, default=10, metavar="K",
                   help="write the XDMF fields every K steps (default 10)")
    o.add_argument("--overwrite", action="store_true", help="replace a finished run in --out")
    o.add_argument("--quiet", action="store_true", help="no progress lines")
    p.epilog = ("PETSc options of the step solver can be added as -sdm_<option> (semi-smooth Newton: "
                "-sdm_ksp_*, -sdm_factor_pc_factor_mat_solver_type; SNES: -sdm_snes_*).")


def build_parser():
    parser = _Parser(prog="python -m sdm_dolfinx",
                     description="The singular dynamic method for dynamic contact (Renard 2010) on dolfinx.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, mod in PROBLEMS.items():
        p = sub.add_parser(name, help=(mod.__doc__ or "").strip().splitlines()[0],
                           description=(mod.__doc__ or "").strip(),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        add_run_arguments(p, mod.DEFAULTS)
    return parser


def _check_run(args, mod):
    errors = list(mod.check_arguments(args))
    if args.T < args.dt:
        errors.append(f"--T ({args.T}) must be >= --dt ({args.dt})")
    if args.write_every < 1:
        errors.append(f"--write-every must be >= 1 (got {args.write_every})")
    pair = get_pair(args.pair)
    if args.mass is not None and args.mass not in pair.allowed_masses():
        errors.append(f"--mass {args.mass} is not available for {pair.name}; choose {', '.join(pair.allowed_masses())}")
    if errors:
        raise UsageError("; ".join(errors))


def _check_out(out, overwrite):
    """The output folder must be writable and must not hold a finished run (unless --overwrite)."""
    run = out / "run.json"
    if run.exists() and not overwrite:
        try:
            status = json.loads(run.read_text()).get("status")
        except (OSError, ValueError):
            status = "unreadable"
        if status == "finished":
            raise UsageError(f"{out} already holds a finished run; use --overwrite or another --out")
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} exists and is not a folder")
    probe_dir = out
    while not probe_dir.exists():
        probe_dir = probe_dir.parent
    if not os.access(probe_dir, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write to {out} ({probe_dir} is not writable)")


def _petsc_overrides(extra):
    """Command-line PETSc options (-sdm_...), passed on to PETSc.Options."""
    opts = PETSc.Options()
    i = 0
    while i < len(extra):
        key = extra[i]
        if not key.startswith("-sdm_"):
            raise UsageError(f"unrecognised argument {key!r} (PETSc options start with -sdm_)")
        value = None
        if i + 1 < len(extra) and not extra[i + 1].startswith("-sdm_"):
            value = extra[i + 1]
            i += 1
        opts.setValue(key[1:], value if value is not None else "")
        i += 1


def main(argv=None):
    comm = MPI.COMM_WORLD
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in SUBCOMMANDS:
        import importlib
        return importlib.import_module(SUBCOMMANDS[argv[0]], __package__).main(argv[1:])
    parser = build_parser()
    try:
        if not argv or argv[0] in ("-h", "--help"):
            if comm.rank == 0:
                parser.print_help()
            return 0 if argv else 2
        args, extra = parser.parse_known_args(argv)
        if args.command is None:
            raise UsageError(f"{parser.prog}: error: choose a command: {', '.join(PROBLEMS)}")
        mod = PROBLEMS[args.command]
        _check_run(args, mod)
        args.out = args.out or Path("output") / args.command
        _check_out(args.out, args.overwrite)
        _petsc_overrides(extra)
    except UsageError as e:
        if comm.rank == 0:
            msg = str(e)
            if not msg.startswith(parser.prog):
                msg = f"{parser.prog} {argv[0] if argv else ''}: error: {msg}"
            print(msg, file=sys.stderr, flush=True)
        return 2
    progress = not args.quiet
    problem = mod.problem_from_args(args, comm)
    if progress and comm.rank == 0:
        print(f"sdm_dolfinx {args.command}: pair {args.pair}, {args.scheme}, dt = {args.dt}, T = {args.T} "
              f"({num_steps(args.T, args.dt)} steps) on {comm.size} rank(s) -> {args.out}", flush=True)
    try:
        result = simulate(problem, pair=args.pair, scheme=args.scheme, dt=args.dt, T=args.T, mass=args.mass,
                          vi_solver=args.vi_solver, linear=args.linear, out=args.out, write_every=args.write_every,
                          progress=progress, extra_info={"command": " ".join(["python -m sdm_dolfinx"] + argv)})
    except StepError as e:
        if comm.rank == 0:
            print(f"{parser.prog} {args.command}: error: {e}; outputs up to the last good step are in {args.out}",
                  file=sys.stderr, flush=True)
        return 1
    if progress and comm.rank == 0:
        i = result.info
        print(f"done in {i['wall_time']:.1f} s: dim W = {i['dim_W']}, dim H = {i['dim_H']}, N_g = {i['N_g']}; "
              f"energy {result.timeseries['energy'][0]:.6g} -> {result.timeseries['energy'][-1]:.6g}; "
              f"wrote {args.out}/timeseries.csv, run.json, solution.xdmf", flush=True)
    return 0
