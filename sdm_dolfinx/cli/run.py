"""The run commands: ``python -m sdm_dolfinx PROBLEM [options]`` for a registered problem and
``python -m sdm_dolfinx run --problem-file FILE [options]`` for a problem of one's own.

The options are the problem's declared parameters and the run options (both declared once;
:mod:`.params` makes them options); ``--config FILE`` reads them from TOML, ``--restart DIR``
continues the run in DIR. Bad input: one line on stderr, exit status 2, nothing written. A failed step: one line, exit
status 1, the files kept up to the last good step and ``run.json`` saying ``"failed"``. An
interrupted run: exit status 128 + the signal, a checkpoint written.
"""
import argparse
import sys
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

from sdm_dolfinx.cli.common import Parser, UsageError, folder_path, say_error
from sdm_dolfinx.cli.config import load_config, read_toml
from sdm_dolfinx.cli import params as declared
from sdm_dolfinx.cli.params import add_param_options, param_values, run_option_values
from sdm_dolfinx.errors import StepError
from sdm_dolfinx.problems import ProblemInputError, get, load_file, spec_of_run
from sdm_dolfinx.problems.disc_mesh import MeshError
from sdm_dolfinx.run import Interrupted, RunInputError, SolverSetupError, grouped, plan
from sdm_dolfinx.io import CheckpointError, RunFolderError, read_info
from sdm_dolfinx.run.options import OUTPUT, RESTART, check_problem_names
from sdm_dolfinx.solvers import VI_OPTIONS
from sdm_dolfinx.solvers.options import unknown_option

PROG = "python -m sdm_dolfinx"

PETSC_EPILOG = (
    "PETSc options of the step solver can be added as -sdm_<option>: -sdm_vi_rtol (default 1e-10, "
    "complementarity tolerance relative to the right-hand side), -sdm_vi_max_it (default 500 for "
    "ssn, 60 for SNES), -sdm_vi_monitor (a line per iteration); the semi-smooth Newton is a PETSc SNES "
    "of type python: -sdm_snes_monitor, -sdm_snes_converged_reason, -sdm_snes_max_it, -sdm_snes_view, "
    "and -sdm_ksp_*, -sdm_factor_pc_factor_mat_solver_type for its linear solves; with --vi-solver "
    "vinewtonrsls: -sdm_snes_*, -sdm_ksp_*, -sdm_pc_*.")


def add_run_options(p, defaults):
    """The run options (declared once: :mod:`sdm_dolfinx.run.options`) and the options of every
    run command (output, configuration, restart)."""
    def output(g):
        g.add_argument("--out", type=folder_path, default=None, help="output folder (default output/<problem>)")

    def output_after(g):
        g.add_argument("--overwrite", action="store_true", help="replace a run in --out")
        g.add_argument("--quiet", action="store_true", help="no progress lines")

    def config(g):
        g.add_argument("--config", type=Path, default=None, metavar="FILE",
                       help="TOML file of option = value pairs (names as here, without --); the command line "
                            "overrides it")

    def restart(g):
        g.add_argument("--restart", type=folder_path, default=None, metavar="DIR",
                       help="continue the run in DIR from its checkpoint, with the problem, parameters and options "
                            "of DIR/run.json (same number of ranks; only --checkpoint-every, --quiet and a later --T "
                            "may be given: --T extends a run, a finished one too)")
        g.add_argument("--allow-changed-source", action="store_true",
                       help="with --restart: continue although the problem file or sdm_dolfinx changed since the run "
                            "started (refused otherwise; run.json records it)")
    declared.add_run_options(p, defaults, before={OUTPUT: output, RESTART: config},
                             after={OUTPUT: output_after, RESTART: restart})
    p.epilog = PETSC_EPILOG


def build_parser(spec, command):
    """The parser of a run command for the problem ``spec`` (None: ``run`` before a problem is chosen)."""
    desc = spec.doc if spec is not None else "Run a problem of your own: --problem-file FILE (docs/add_a_problem.md)."
    p = Parser(prog=f"{PROG} {command}", description=desc, formatter_class=argparse.RawDescriptionHelpFormatter)
    if command == "run":
        g = p.add_argument_group("problem")
        g.add_argument("--problem", default=None, metavar="NAME", help="a registered problem (membrane, disc, ...)")
        g.add_argument("--problem-file", type=Path, default=None, metavar="FILE",
                       help="a Python file defining PROBLEM = ProblemSpec(...) (docs/add_a_problem.md)")
    if spec is not None:
        add_param_options(p, spec)
    add_run_options(p, spec.defaults if spec is not None else {})
    return p


def _choose_spec(command, argv):
    """The problem's declaration: the command's, or for ``run`` the one named by --problem /
    --problem-file (also as TOML keys), or the restarted run's."""
    pre = Parser(add_help=False, prog=f"{PROG} {command}")
    for opt in ("--problem", "--problem-file", "--config", "--restart"):
        pre.add_argument(opt, default=None)
    known, _ = pre.parse_known_args(argv)
    if known.restart is not None:
        try:
            info = read_info(known.restart, MPI.COMM_WORLD)
            spec = spec_of_run(info.get("problem", {"name": None}))
        except (RunFolderError, ProblemInputError, KeyError) as e:
            raise UsageError(f"--restart {known.restart}: {e}") from None
        if command != "run" and spec.name != command:
            raise UsageError(f"--restart {known.restart}: that folder holds a {spec.name!r} run, not {command!r}")
        return spec
    if command != "run":
        return get(command)
    name, path = known.problem, known.problem_file
    if known.config is not None:
        data = read_toml(Path(known.config))
        name = name or data.get("problem")
        if path is None and data.get("problem-file") is not None:
            path = Path(known.config).parent / Path(str(data["problem-file"])).expanduser()  # relative to the TOML
    if name is not None and path is not None:
        raise UsageError("--problem and --problem-file: choose one")
    if path is not None:
        return load_file(path)
    if name is not None:
        return get(name)
    return None


def parse(command, argv):
    """(spec, args, extra PETSc arguments) of a run command."""
    spec = _choose_spec(command, argv)
    if spec is not None:
        try:
            check_problem_names(spec)           # its --options would clash with the parser's
        except RunInputError as e:
            raise UsageError(str(e)) from None
    parser = build_parser(spec, command)
    if spec is None:
        if "-h" in argv or "--help" in argv:
            return None, parser, None
        raise UsageError(f"{PROG} run: error: choose the problem: --problem NAME or --problem-file FILE")
    _KNOWN_OPTIONS[:] = [o for a in parser._actions for o in a.option_strings if o.startswith("--")]
    args, extra = parser.parse_known_args(argv)
    if args.config is not None:
        data = read_toml(args.config)
        if command != "run" and data.get("problem", command) != command:
            raise UsageError(f"{args.config}: key 'problem' is {data.get('problem')!r} but the command is "
                             f"{command!r}")
        parser.set_defaults(**load_config(args.config, parser, data))
        _check_config_params(args.config, data, spec)
        args, extra = parser.parse_known_args(argv)
    if "-h" in argv or "--help" in argv:
        return spec, parser, None
    return spec, args, extra


def _check_config_params(path, data, spec):
    """The problem's parameters given in the TOML file, each checked against its declaration,
    naming the file and the key (the command line may still override them)."""
    errors = []
    for key, value in data.items():
        for p in spec.params:
            if key in (p.option, p.name, p.option.replace("-", "_")) and p.kind is not bool:
                errors += p.check(value, f"{path}: key '{key}' (--{p.option})")
    if errors:
        raise UsageError("; ".join(errors))


def make_plan(spec, args, command, comm):
    """The checked :class:`~sdm_dolfinx.run.RunPlan` (UsageError with every reason otherwise)."""
    params = param_values(args, spec)
    opts = grouped(run_option_values(args))
    if args.allow_changed_source and args.restart is None:
        raise UsageError("--allow-changed-source is for --restart DIR only")
    try:
        if args.restart is not None:
            if params:
                raise UsageError(f"--restart continues the run with its own parameters; remove "
                                 f"{', '.join('--' + spec.param(k).option for k in params)}")
            if args.out is not None and args.out != args.restart:
                raise UsageError("--restart continues the run in its own folder; remove --out")
            return plan(out=args.restart, restart=True, overwrite=args.overwrite, comm=comm, cli=True,
                        allow_changed_source=args.allow_changed_source, **opts)
        out = args.out if args.out is not None else Path("output") / spec.name
        return plan(spec, params, out=out, overwrite=args.overwrite, comm=comm, cli=True, **opts)
    except RunInputError as e:
        raise UsageError(str(e)) from None


def petsc_arguments(extra):
    """The (key, value) pairs of the arguments the parser did not know, each checked: a PETSc
    option of the step solver (-sdm_...), else refused as unrecognised (UsageError)."""
    pairs = []
    i = 0
    while i < len(extra):
        key = extra[i]
        if not key.startswith("-sdm_"):
            raise UsageError(_unrecognised(key))
        value = None
        if i + 1 < len(extra) and not extra[i + 1].startswith("-sdm_"):
            value = extra[i + 1]
            i += 1
        unknown = unknown_option(key)
        if unknown:
            raise UsageError(unknown)
        _check_vi_option(key, value)
        pairs.append((key, value))
        i += 1
    return pairs


def set_petsc_options(pairs):
    """Pass checked (key, value) pairs (:func:`petsc_arguments`) on to PETSc.Options."""
    opts = PETSc.Options()
    for key, value in pairs:
        opts.setValue(key[1:], value if value is not None else "")
    if pairs and not opts.hasName("options_left"):
        # PETSc lists the options nobody read when it finalises (a misspelt -sdm_ option
        # would otherwise be ignored in silence)
        opts.setValue("options_left", "")


#: PETSc options of the step solvers checked before anything runs: the solvers' own (VI_OPTIONS)
#: and SNES's iteration limit (-sdm_snes_max_it -5 made the semi-smooth Newton do no iteration)
CHECKED_OPTIONS = {**VI_OPTIONS, "snes_max_it": (int, lambda v: v >= 1, "an integer >= 1"),
                   "schur_max_active": (int, lambda v: v >= 1, "an integer >= 1"),
                   "gap_max_columns": (int, lambda v: v >= 0, "an integer >= 0"),
                   "inexact_rtol": (float, lambda v: 0 <= v < 1, "a number in [0, 1)")}


#: the parser whose options an unrecognised argument is compared with (set by :func:`parse`)
_KNOWN_OPTIONS: list[str] = []


def _unrecognised(key):
    """``unrecognised argument``, with the nearest option when there is one."""
    import difflib
    if key.startswith("--"):
        typed = key.split("=")[0].replace("_", "-")
        same_letters = [o for o in _KNOWN_OPTIONS if o.lower() == typed.lower()]      # --Nx for --nx
        near = same_letters or difflib.get_close_matches(typed, _KNOWN_OPTIONS, n=1, cutoff=0.6)
        return f"unrecognised option {key!r}" + (f"; did you mean {near[0]}?" if near else "")
    return f"unrecognised argument {key!r} (PETSc options of the step solver start with -sdm_)"


def _check_vi_option(key, value):
    """The -sdm_ options of :data:`CHECKED_OPTIONS`, checked before anything runs."""
    name = key[len("-sdm_"):]
    if name not in CHECKED_OPTIONS:
        return
    kind, ok, allowed = CHECKED_OPTIONS[name]
    try:
        good = ok(kind(value if value is not None else ""))
    except ValueError:
        good = False
    if not good:
        raise UsageError(f"{key}: {value!r} is not {allowed}")


def main(command, argv, comm=MPI.COMM_WORLD):
    """A run command; returns the exit status (0 ok, 1 failed run, 2 bad input, 128+sig interrupted)."""
    prog = f"{PROG} {command}"
    try:
        spec, args, extra = parse(command, argv)
        if extra is None:                       # --help
            if comm.rank == 0:
                args.print_help()
            return 0
        pairs = petsc_arguments(extra)          # a misspelt option first: the others may depend on it
        the_plan = make_plan(spec, args, command, comm)
        set_petsc_options(pairs)
    except (UsageError, ProblemInputError) as e:
        msg = str(e)
        return say_error(prog, msg.split("error: ", 1)[1] if msg.startswith(prog) else msg, comm, 2)
    return execute(the_plan, args, argv, prog, comm)


def execute(the_plan, args, argv, prog, comm):
    """Run a checked plan from the command line: progress, one-line errors, exit status."""
    progress = not args.quiet
    o = the_plan.options
    if progress and comm.rank == 0:
        what = f"restarting {the_plan.out}" if the_plan.restart else f"-> {the_plan.out}"
        print(f"sdm_dolfinx {the_plan.spec.name}: pair {o['pair']}, {o['scheme']}, dt = {o['dt']}, T = {o['T']} "
              f"({the_plan.steps} steps) on {comm.size} rank(s) {what}", flush=True)
    try:
        result = the_plan.run(comm, progress=progress, handle_signals=True,
                              extra_info={"command": " ".join([prog] + list(argv))})
    except (ProblemInputError, RunFolderError) as e:   # refused values, a problem file's bug, a folder in use
        return say_error(prog, e, comm, 2)
    except MeshError as e:              # raised on every rank, before anything is written
        return say_error(prog, e, comm, 2)
    except StepError as e:
        return say_error(prog, f"{e}; outputs up to the last good step are in {the_plan.out}", comm, 1)
    except CheckpointError as e:
        return say_error(prog, e, comm, 2)
    except SolverSetupError as e:       # nothing written yet; with -sdm_ options most likely theirs
        user = any(a.startswith("-sdm_") for a in argv)
        return say_error(prog, f"{e}" + ("; check the -sdm_ options" if user else ""), comm, 2 if user else 1)
    except Interrupted as e:
        if comm.rank == 0:
            print(f"{prog}: {e}", file=sys.stderr, flush=True)
        return 128 + int(e.signum)
    if progress and comm.rank == 0:
        i = result.info
        print(f"done in {i['wall_time']:.1f} s: dim W = {i['dim_W']}, dim H = {i['dim_H']}, N_g = {i['N_g']}; "
              f"energy {result.timeseries['energy'][0]:.6g} -> {result.timeseries['energy'][-1]:.6g}; "
              f"wrote {the_plan.out}/timeseries.csv, run.json, solution.xdmf"
              + (", obstacles.xdmf" if (i.get("problem") or {}).get("obstacles") else ""), flush=True)
    return 0
