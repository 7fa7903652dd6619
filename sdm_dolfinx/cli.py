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
import tempfile
try:
    import tomllib                  # Python >= 3.11
except ModuleNotFoundError:        # pragma: no cover
    import tomli as tomllib
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

from . import disc, membrane
from .checkpoint import CheckpointError
from .disc_mesh import MeshError
from .integrator import SCHEMES, StepError
from .pairs import MASS_TREATMENTS, PAIRS, get_pair
from .simulate import Interrupted, SolverSetupError, num_steps, simulate
from .vi import LINEAR_STRATEGIES, VI_OPTIONS, VI_SOLVERS

PROBLEMS = {"membrane": membrane, "disc": disc}
#: commands that are not a run: name -> module with ``main(argv) -> exit status``
SUBCOMMANDS = {"inspect": ".wellposed", "figures": ".figures", "energy": ".postprocess"}
#: one-line descriptions of SUBCOMMANDS for the top-level ``--help`` (their modules are imported only when run)
SUBCOMMAND_HELP = {
    "inspect": "measure the inf-sup condition (7) of a problem, pair and mesh (well-posedness)",
    "figures": "rerun the paper's studies (only what is missing) and regenerate its figures and Table 2",
    "energy": "recompute a finished run's energy history from its state.h5",
}


class UsageError(Exception):
    """Bad input: reported in one line with exit status 2."""


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors raise UsageError (one line, status 2) instead of exiting."""

    def error(self, message):
        raise UsageError(f"{self.prog}: error: {message}")


def parse_or_help(parser, argv, comm):
    """A subcommand's arguments, or None after printing its ``--help`` (on rank 0).

    Raises:
        UsageError: bad arguments (``parser`` is a :class:`_Parser`).
    """
    if "-h" in argv or "--help" in argv:
        if comm.rank == 0:
            parser.print_help()
        return None
    return parser.parse_args(argv)


def report_usage_error(prog, error, comm):
    """Print a :class:`UsageError` as one line on stderr (rank 0), prefixed with ``prog``;
    returns the exit status 2."""
    if comm.rank == 0:
        msg = str(error)
        print(msg if msg.startswith(prog) else f"{prog}: error: {msg}", file=sys.stderr, flush=True)
    return 2


def _positive_float(text):
    """argparse type: a finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number (got {text})")
    return v


def add_run_arguments(p, defaults):
    """Add the options common to every run command (pair, scheme, dt, T, solver, output, restart) to ``p``."""
    g = p.add_argument_group("discretisation and run")
    g.add_argument("--pair", default=defaults["pair"], choices=list(PAIRS), metavar="PAIR",
                   help=f"(W^h, H^h) pair: {', '.join(PAIRS)} (default {defaults['pair']})")
    g.add_argument("--mass", choices=MASS_TREATMENTS, default=None,
                   help="C treatment: diagonal (P0), lumped or consistent (P1 velocity; consistent solves the "
                        "(U, V) block system), standard (H = W); default: diagonal for P0, lumped for P1")
    g.add_argument("--scheme", default=defaults["scheme"], choices=list(SCHEMES),
                   help=f"time scheme (default {defaults['scheme']})")
    unit = defaults.get("time_unit", "")
    unit = f", {unit}" if unit else ""
    g.add_argument("--dt", type=_positive_float, default=defaults["dt"],
                   help=f"time step (default {defaults['dt']}{unit})")
    g.add_argument("--T", type=_positive_float, default=defaults["T"],
                   help=f"final time (default {defaults['T']}{unit})")
    g.add_argument("--vi-solver", choices=VI_SOLVERS, default="ssn",
                   help="step solver: ssn = semi-smooth Newton / primal-dual active set (default), or PETSc SNES "
                        "vinewtonrsls / vinewtonssls")
    g.add_argument("--linear", choices=LINEAR_STRATEGIES, default="auto",
                   help="linear solves of the semi-smooth Newton: auto = schur, or amg above 10000 constrained "
                        "dofs (default); schur = one factorisation of the step matrix per run, the active set by a "
                        "small dense Schur complement of cached columns K^-1 e_i; cg-factor = one factorisation, CG "
                        "on the inactive set; lu = refactorise at every Newton iteration; amg = CG + BoomerAMG on "
                        "the reduced matrix (set up when the active set changes); cg-amg = CG on the inactive set "
                        "with one BoomerAMG set-up of the step matrix")
    o = p.add_argument_group("output")
    o.add_argument("--out", type=Path, default=None, help="output folder (default output/<problem>)")
    o.add_argument("--write-every", type=int, default=10, metavar="K",
                   help="write the XDMF fields every K steps (default 10)")
    o.add_argument("--overwrite", action="store_true", help="replace a finished run in --out")
    o.add_argument("--quiet", action="store_true", help="no progress lines")
    r = p.add_argument_group("configuration and restart")
    r.add_argument("--config", type=Path, default=None, metavar="FILE",
                   help="TOML file of option = value pairs (names as here, without --); the command line overrides it")
    r.add_argument("--checkpoint-every", type=int, default=None, metavar="K",
                   help="write DIR/checkpoint.npz every K steps (a SIGINT/SIGTERM always writes one)")
    r.add_argument("--restart", type=Path, default=None, metavar="DIR",
                   help="continue the run in DIR from its checkpoint with the parameters of DIR/run.json "
                        "(same number of ranks)")
    p.epilog = ("PETSc options of the step solver can be added as -sdm_<option>: -sdm_vi_rtol (default 1e-10, "
                "complementarity tolerance relative to the right-hand side), -sdm_vi_max_it (default 500 for "
                "ssn, 60 for SNES), -sdm_vi_monitor (a line per iteration); the semi-smooth Newton is a PETSc SNES "
                "of type python: -sdm_snes_monitor, -sdm_snes_converged_reason, -sdm_snes_max_it, -sdm_snes_view, "
                "and -sdm_ksp_*, -sdm_factor_pc_factor_mat_solver_type for its linear solves; with --vi-solver "
                "vinewtonrsls: -sdm_snes_*, -sdm_ksp_*, -sdm_pc_*.")


def build_parser():
    """The top-level parser and a dict problem name -> its run parser.

    The top-level ``--help`` names every command: the problems (runs, parsed here) and the
    SUBCOMMANDS, which ``main`` hands to their own modules before argparse sees them (they are
    registered here without options, for the listing only).
    """
    parser = _Parser(prog="python -m sdm_dolfinx",
                     description="The singular dynamic method for dynamic contact (Renard 2010) on dolfinx.",
                     epilog="`python -m sdm_dolfinx COMMAND --help` lists the options of a command.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    subparsers = {}
    for name, mod in PROBLEMS.items():
        p = sub.add_parser(name, help="run: " + (mod.__doc__ or "").strip().splitlines()[0],
                           description=(mod.__doc__ or "").strip(),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        add_run_arguments(p, mod.DEFAULTS)
        subparsers[name] = p
    for name, text in SUBCOMMAND_HELP.items():
        sub.add_parser(name, help=text, add_help=False)
    return parser, subparsers


#: the longest run accepted (--T / --dt): ~100 bytes of time series per step in memory
MAX_STEPS = 1e7


def _check_run(args, mod):
    errors = list(mod.check_arguments(args))
    if args.T < args.dt:
        errors.append(f"--T ({args.T}) must be >= --dt ({args.dt})")
    elif args.T / args.dt > MAX_STEPS:
        errors.append(f"--T / --dt = {args.T / args.dt:.3g} steps: at most {MAX_STEPS:.0e} (the time series "
                      f"alone would take {args.T / args.dt * 100 / 1e9:.3g} GB)")
    if args.write_every < 1:
        errors.append(f"--write-every must be >= 1 (got {args.write_every})")
    if args.checkpoint_every is not None and args.checkpoint_every < 1:
        errors.append(f"--checkpoint-every must be >= 1 (got {args.checkpoint_every})")
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
        if status == "failed":
            raise UsageError(f"{out} holds a failed run (see its run.json); use --overwrite or another --out")
        if status == "running":
            has = (out / "checkpoint.npz").exists()
            raise UsageError(f"{out} holds a run that is still going or was killed"
                             + (f"; continue it with --restart {out}" if has else "")
                             + ", or use --overwrite")
        if status == "interrupted":
            raise UsageError(f"{out} holds an interrupted run; continue it with --restart {out}, "
                             f"or use --overwrite")
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} exists and is not a folder")
    probe_dir = out
    while not probe_dir.exists():
        probe_dir = probe_dir.parent
    if not probe_dir.is_dir() or not os.access(probe_dir, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write to {out} ({probe_dir} is not a writable folder)")
    # os.access says yes to root on a read-only file system (/proc, a read-only mount): try
    # a temporary file in the folder that exists (removed at once: nothing is left behind)
    comm = MPI.COMM_WORLD
    problem = None
    if comm.rank == 0:
        try:
            with tempfile.TemporaryFile(dir=probe_dir):
                pass
        except OSError as e:
            problem = f"cannot write to {out} (creating a file in {probe_dir} failed: {e.strerror or e})"
    problem = comm.bcast(problem, root=0)
    if problem:
        raise UsageError(problem)


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
        _check_vi_option(key, value)
        opts.setValue(key[1:], value if value is not None else "")
        i += 1
    if extra and not opts.hasName("options_left"):
        # PETSc lists the options nobody read when it finalises (a misspelt -sdm_ option
        # would otherwise be ignored in silence)
        opts.setValue("options_left", "")


def _check_vi_option(key, value):
    """The step solver's own -sdm_vi_* options, checked before anything runs (vi.VI_OPTIONS)."""
    name = key[len("-sdm_"):]
    if name not in VI_OPTIONS:
        return
    kind, ok, allowed = VI_OPTIONS[name]
    try:
        good = ok(kind(value if value is not None else ""))
    except ValueError:
        good = False
    if not good:
        raise UsageError(f"{key}: {value!r} is not {allowed}")


def _config_value(path, action, key, value):
    """Check one TOML value against the option's argparse action; returns the value to use."""
    def bad(expected):
        return UsageError(f"{path}: key '{key}': expected {expected}, got {value!r}")
    if isinstance(action, argparse._StoreTrueAction):
        if not isinstance(value, bool):
            raise bad("true or false")
        return value
    if action.nargs == 2:
        if not (isinstance(value, list) and len(value) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
            raise bad("a list of 2 numbers")
        return [float(v) for v in value]
    if action.type is int:
        if not isinstance(value, int) or isinstance(value, bool):
            raise bad("an integer")
        return value
    if action.type in (float, _positive_float):
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise bad("a number")
        try:
            return action.type(str(value))
        except argparse.ArgumentTypeError as e:
            raise UsageError(f"{path}: key '{key}': {e}") from None
    if action.type is Path:
        if not isinstance(value, str):
            raise bad("a path (string)")
        return Path(value)
    if not isinstance(value, str):
        raise bad("a string" + (f" among {', '.join(map(str, action.choices))}" if action.choices else ""))
    if action.choices is not None and value not in action.choices:
        raise UsageError(f"{path}: key '{key}': {value!r} is not one of {', '.join(map(str, action.choices))}")
    return value


def load_config(path, subparser, command):
    """Option defaults from a TOML file, every key and value checked."""
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise UsageError(f"config file {path} not found") from None
    except OSError as e:
        raise UsageError(f"cannot read config file {path}: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise UsageError(f"{path}: invalid TOML: {e}") from None
    except UnicodeDecodeError:
        raise UsageError(f"{path}: not a TOML file (TOML is UTF-8 text)") from None
    problem = data.pop("problem", command)
    if problem != command:
        raise UsageError(f"{path}: key 'problem' is {problem!r} but the command is {command!r}")
    actions = {a.dest: a for a in subparser._actions if a.dest not in ("help", "config", "restart")}
    defaults, seen = {}, {}
    for key, value in data.items():
        dest = key.replace("-", "_")
        if dest in seen:
            raise UsageError(f"{path}: keys '{seen[dest]}' and '{key}' are the same option")
        seen[dest] = key
        if dest not in actions:
            raise UsageError(f"{path}: unknown key '{key}'; allowed keys: problem, "
                             f"{', '.join(sorted(a.replace('_', '-') for a in actions))}")
        defaults[dest] = _config_value(path, actions[dest], key, value)
    return defaults


def _restart_args(args, subparser, command):
    """The namespace of the run being continued (from DIR/run.json)."""
    run = args.restart / "run.json"
    try:
        saved = json.loads(run.read_text())
    except FileNotFoundError:
        raise UsageError(f"--restart {args.restart}: no run.json there") from None
    except (OSError, ValueError) as e:
        raise UsageError(f"--restart {args.restart}: cannot read run.json ({e})") from None
    if saved.get("command_name") != command:
        raise UsageError(f"--restart {args.restart}: that folder holds a {saved.get('command_name')!r} run, "
                         f"not {command!r}")
    if saved.get("status") == "finished":
        raise UsageError(f"--restart {args.restart}: that run is already finished")
    ns = subparser.parse_args([])
    for k, v in saved["cli_args"].items():
        setattr(ns, k, Path(v) if k in ("out", "config") and v is not None else v)
    ns.command, ns.restart, ns.out, ns.quiet = command, args.restart, args.restart, args.quiet
    ns.checkpoint_every = args.checkpoint_every or ns.checkpoint_every
    return ns


def _parse(argv, parser, subparsers):
    args, extra = parser.parse_known_args(argv)
    if args.command is None:
        raise UsageError(f"{parser.prog}: error: choose a command: {', '.join([*PROBLEMS, *SUBCOMMANDS])}")
    sub = subparsers[args.command]
    if args.config is not None:
        sub.set_defaults(**load_config(args.config, sub, args.command))
        args, extra = parser.parse_known_args(argv)
    if args.restart is not None:
        args = _restart_args(args, sub, args.command)
    return args, extra


def main(argv=None):
    """Entry point; returns the exit status (0 ok, 1 failed run, 2 bad input, 128+sig interrupted)."""
    comm = MPI.COMM_WORLD
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in SUBCOMMANDS:
        import importlib
        try:
            return importlib.import_module(SUBCOMMANDS[argv[0]], __package__).main(argv[1:])
        except Exception as e:
            return internal_error(f"python -m sdm_dolfinx {argv[0]}", e, comm)
    parser, subparsers = build_parser()
    try:
        if not argv or argv[0] in ("-h", "--help"):
            if comm.rank == 0:
                parser.print_help()
            return 0 if argv else 2
        args, extra = _parse(argv, parser, subparsers)
        mod = PROBLEMS[args.command]
        _check_run(args, mod)
        args.out = args.out or Path("output") / args.command
        if args.restart is None:
            _check_out(args.out, args.overwrite)
        _petsc_overrides(extra)
    except UsageError as e:
        if comm.rank == 0:
            msg = str(e)
            if not msg.startswith(parser.prog):
                msg = f"{parser.prog} {argv[0] if argv else ''}: error: {msg}"
            print(msg, file=sys.stderr, flush=True)
        return 2
    try:
        return _run(args, argv, mod, parser, comm)
    except Exception as e:
        return internal_error(f"{parser.prog} {args.command}", e, comm)


def internal_error(prog, e, comm):
    """An unexpected exception: say it in one line (SDM_DEBUG=1 shows the traceback) and take
    every rank down (no deadlock when one rank fails alone); returns exit status 1."""
    print(f"{prog}: internal error on rank {comm.rank}: {type(e).__name__}: {e}", file=sys.stderr, flush=True)
    if os.environ.get("SDM_DEBUG"):
        raise e
    if comm.size > 1:
        comm.Abort(1)
    return 1


def _run(args, argv, mod, parser, comm):
    progress = not args.quiet
    prog = f"{parser.prog} {args.command}"
    try:
        problem = mod.problem_from_args(args, comm)
    except MeshError as e:              # raised on every rank, before anything is written
        if comm.rank == 0:
            print(f"{prog}: error: {e}", file=sys.stderr, flush=True)
        return 2
    if progress and comm.rank == 0:
        what = f"restarting {args.restart}" if args.restart else f"-> {args.out}"
        print(f"sdm_dolfinx {args.command}: pair {args.pair}, {args.scheme}, dt = {args.dt}, T = {args.T} "
              f"({num_steps(args.T, args.dt)} steps) on {comm.size} rank(s) {what}", flush=True)
    cli_args = {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()
                if k not in ("restart", "overwrite", "quiet", "command")}
    try:
        result = simulate(problem, pair=args.pair, scheme=args.scheme, dt=args.dt, T=args.T, mass=args.mass,
                          vi_solver=args.vi_solver, linear=args.linear, out=args.out, write_every=args.write_every,
                          progress=progress, checkpoint_every=args.checkpoint_every,
                          restart=args.restart is not None, handle_signals=True,
                          extra_info={"command": " ".join(["python -m sdm_dolfinx"] + argv),
                                      "command_name": args.command, "cli_args": cli_args})
    except StepError as e:
        if comm.rank == 0:
            print(f"{prog}: error: {e}; outputs up to the last good step are in {args.out}",
                  file=sys.stderr, flush=True)
        return 1
    except CheckpointError as e:
        if comm.rank == 0:
            print(f"{prog}: error: {e}", file=sys.stderr, flush=True)
        return 2
    except SolverSetupError as e:       # nothing written yet; with -sdm_ options most likely theirs
        user = any(a.startswith("-sdm_") for a in argv)
        if comm.rank == 0:
            print(f"{prog}: error: {e}" + ("; check the -sdm_ options" if user else ""), file=sys.stderr, flush=True)
        return 2 if user else 1
    except Interrupted as e:
        if comm.rank == 0:
            print(f"{prog}: {e}", file=sys.stderr, flush=True)
        return 128 + int(e.signum)
    if progress and comm.rank == 0:
        i = result.info
        print(f"done in {i['wall_time']:.1f} s: dim W = {i['dim_W']}, dim H = {i['dim_H']}, N_g = {i['N_g']}; "
              f"energy {result.timeseries['energy'][0]:.6g} -> {result.timeseries['energy'][-1]:.6g}; "
              f"wrote {args.out}/timeseries.csv, run.json, solution.xdmf", flush=True)
    return 0
