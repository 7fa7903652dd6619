"""``python -m sdm_dolfinx inspect [PROBLEM] [options]``: the inf-sup condition (7) of a problem,
a pair and a mesh (:mod:`sdm_dolfinx.analysis.infsup`).

The problem is a registered one (``--problem NAME``, default membrane; the first argument
``inspect NAME`` is a deprecated alias, with a note on stderr) or a user's problem file
(``--problem-file FILE``); its options are those it declares, as for
the run commands. ``--sweep`` runs a sequence of meshes (the membrane's ``--N``, the disc's
``--level``). ``--constrain nodes`` measures (7) with the constraint at every dof of W^h on the
constrained boundary (P2's mid-edge nodes too) instead of the vertices (eq. (13)). Bad input: one
line on stderr, exit status 2; a measurement that cannot be made: exit status 1.
"""
import sys
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx import compat, problems
from sdm_dolfinx.cli.common import (Parser, UsageError, check_writable, nonnegative_float, parse_or_help,
                                    positive_float, positive_int, report_usage_error, say_error)
from sdm_dolfinx.cli.params import add_param_options, param_values
from sdm_dolfinx import schemes
from sdm_dolfinx.method.discretisation import CONSTRAIN
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.method.pairs import PAIRS
from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.analysis import DENSE_MAX, SWEEP_HEADER, TOL, InspectError, inspect, plot_sweep, report, sweep, sweep_line
from sdm_dolfinx.analysis.coulomb_bound import bound_line, coulomb_bound
from sdm_dolfinx.problems import ProblemInputError
from sdm_dolfinx.problems.disc_mesh import MeshError
from sdm_dolfinx.run import RunInputError
from sdm_dolfinx.run.memory import check_memory
from sdm_dolfinx.run.options import check_problem_names

PROG = "python -m sdm_dolfinx inspect"
#: the problem when none is named
DEFAULT_PROBLEM = "membrane"
#: the mesh parameter a sweep varies, and its default values, per built-in problem
SWEEPS = {"membrane": ("N", (4, 8, 16, 32, 64)), "disc": ("level", (1, 2, 3))}


def _sweep_of(spec):
    """(parameter, default values) of a sweep for ``spec``, or None (a user's problem has none)."""
    return SWEEPS.get(spec.name) if spec.source is None else None


def choose_spec(argv, comm=MPI.COMM_WORLD):
    """The problem's declaration: ``--problem NAME``, the first argument if it is not an option
    (deprecated: a note on stderr) or ``--problem-file FILE`` (default: the membrane). UsageError
    for an unknown one."""
    pre = Parser(add_help=False, prog=PROG)
    pre.add_argument("--problem", default=None)
    pre.add_argument("--problem-file", type=Path, default=None)
    known, _ = pre.parse_known_args(argv)
    first = argv[0] if argv and not argv[0].startswith("-") else None
    if first is not None and known.problem is not None and first != known.problem:
        raise UsageError(f"two problems named: {first} and --problem {known.problem}")
    if first is not None and comm.rank == 0 and "-h" not in argv and "--help" not in argv:
        print(f"{PROG}: note: 'inspect {first}' is deprecated: write 'inspect --problem {first}'", file=sys.stderr,
              flush=True)
    name = first or known.problem
    if known.problem_file is not None:
        if name is not None:
            raise UsageError(f"a problem name ({name}) and --problem-file: choose one")
        try:
            spec = problems.load_file(known.problem_file)
            check_problem_names(spec)           # its --options would clash with the parser's
            return spec
        except (ProblemInputError, RunInputError) as e:
            raise UsageError(str(e)) from None
    if name is None:
        return problems.get(DEFAULT_PROBLEM)
    if name not in problems.names():
        raise UsageError(f"argument --problem: invalid choice: {name!r} (choose from "
                         f"{', '.join(sorted(problems.names()))}, or --problem-file FILE)")
    return problems.get(name)


def build_parser(spec):
    """The ``inspect`` parser, with the options ``spec`` declares."""
    p = Parser(prog=PROG,
               description="Measure the inf-sup condition (7) of Renard (2010) for a problem, a pair and a mesh: "
                           "dimensions, Ker(B), rank of M = B^T C^-1 B, beta and a verdict.",
               epilog="Only the problem options that change the mesh or the constraint set (e.g. the membrane's "
                      "--N, --diagonal, --no-obstacle; the disc's --level, --h, --radius, --contact-zone, "
                      "--no-contact) change the result; the others are accepted for symmetry with the run commands.")
    p.add_argument("problem_name", nargs="?", default=None, metavar="PROBLEM",
                   help="deprecated: the same as --problem PROBLEM")
    p.add_argument("--problem", default=None, metavar="NAME",
                   help=f"a registered problem: {', '.join(problems.names())} (default {DEFAULT_PROBLEM})")
    p.add_argument("--problem-file", type=Path, default=None, metavar="FILE",
                   help="a Python file defining PROBLEM = ProblemSpec(...) (docs/add_a_problem.md)")
    default_pair = spec.defaults.get("pair", "P1+/P0")
    p.add_argument("--pair", nargs="+", default=[default_pair], metavar="PAIR",
                   help=f"one or more pairs, or 'all': {', '.join(PAIRS)} (default: the problem's, "
                        f"{default_pair} for {spec.name})")
    param, default_values = _sweep_of(spec) or ("?", ())
    p.add_argument("--sweep", nargs="*", type=positive_int, default=None, metavar="V",
                   help=f"run a sequence of meshes: values of --{param} (default {' '.join(map(str, default_values))})"
                        " and print beta against h" if default_values else
                        "run a sequence of meshes (the membrane's --N, the disc's --level; not for this problem)")
    p.add_argument("--constrain", default="vertices", choices=CONSTRAIN,
                   help="where K^h acts: the constrained vertices (eq. (13), default) or every dof of W^h on the "
                        "constrained boundary (nodes: P2's mid-edge nodes too; pairs whose W^h has no other "
                        "boundary dofs than the vertices, P1 and P1+, are skipped with --pair all)")
    p.add_argument("--coulomb-bound", action="store_true",
                   help="also measure the Coulomb coefficient below which the frictional step problem stays "
                        "well-posed (2-D vector problems: the Newton matrix with every constrained vertex in "
                        "contact and slipping stays positive definite; it depends on --dt and --scheme)")
    p.add_argument("--dt", type=positive_float, default=None,
                   help=f"time step of --coulomb-bound (default: the problem's, {spec.defaults.get('dt', 1e-3)})")
    p.add_argument("--scheme", default="midpoint", choices=list(schemes.names()),
                   help="time scheme of --coulomb-bound (default midpoint)")
    p.add_argument("--json", type=Path, default=None, metavar="FILE", help="write the results as JSON")
    p.add_argument("--png", type=Path, default=None, metavar="FILE",
                   help="with --sweep: the beta-h plot (default output/inspect/<problem>-beta.png)")
    p.add_argument("--tol", type=nonnegative_float, default=TOL,
                   help=f"beta <= tol counts as 0 (default 100 sqrt(eps) = {TOL:.2e})")
    p.add_argument("--dense-max", type=int, default=DENSE_MAX, metavar="N",
                   help=f"dense SVD up to dim W^h = N, iterative beyond (default {DENSE_MAX})")
    add_param_options(p, spec)
    return p


def check(args, spec):
    """Every input error of parsed ``args`` in one UsageError; fills in the pairs, the sweep's
    values and the plot's path. Returns the problem's parameter values given."""
    given = param_values(args, spec)
    errors = []
    if args.problem_name not in (None, spec.name):
        errors.append(f"unrecognized arguments: {args.problem_name}")
    pairs = list(PAIRS) if args.pair == ["all"] else args.pair
    bad = [q for q in pairs if q not in PAIRS]
    if bad:
        errors.append(f"unknown pair {bad[0]!r}; choose from {', '.join(PAIRS)} or all")
    args.pair = list(dict.fromkeys(pairs))
    errors += _check_nodes(args, pairs == list(PAIRS))
    try:
        values = spec.values(given, cli=True)
        if args.sweep is None:
            errors += _memory(spec, values, args.pair)
    except ProblemInputError as e:
        errors.append(str(e))
    if args.dense_max < 0:
        errors.append(f"--dense-max must be >= 0 (got {args.dense_max})")
    if args.sweep is not None and args.coulomb_bound:
        errors.append("--coulomb-bound measures one mesh: drop --sweep")
    if args.dt is not None and not args.coulomb_bound:
        errors.append("--dt is for --coulomb-bound")
    args.dt = args.dt or spec.defaults.get("dt", 1e-3)
    if args.sweep is not None:
        errors += _check_sweep(args, spec, given)
    elif args.png is not None:
        errors.append("--png needs --sweep")
    if errors:
        raise UsageError("; ".join(errors))
    if args.json is not None:
        check_writable(args.json, "--json")
    if args.sweep is not None:
        args.png = args.png or Path("output") / "inspect" / f"{spec.name}-beta.png"
        check_writable(args.png, "--png")
    return given


def _check_nodes(args, every):
    """Messages for --constrain nodes with pairs whose W^h has only vertex dofs on the boundary (P1,
    P1+): skipped (``args.skipped``) when every pair was asked for, an error when named."""
    args.skipped = []
    errors = ([f"--coulomb-bound measures the vertex constraint: drop --constrain {args.constrain}"]
              if args.coulomb_bound and args.constrain != "vertices" else [])
    if args.constrain != "nodes":
        return errors
    vertex_only = [q for q in args.pair if q in PAIRS and not (PAIRS[q].w[0] == "P" and PAIRS[q].w[1] >= 2)]
    if every:
        args.skipped = vertex_only
        args.pair = [q for q in args.pair if q not in vertex_only]
    elif vertex_only:
        errors.append(f"--constrain nodes is --constrain vertices for pair {vertex_only[0]} (its W^h has no dof on "
                      f"the constrained boundary but at the vertices); use a P2 displacement pair or drop it")
    return errors


def _check_sweep(args, spec, given):
    """Messages for a --sweep that cannot run; fills in its default values."""
    if _sweep_of(spec) is None:
        return [f"--sweep is not available for problem {spec.name}"]
    param, default_values = _sweep_of(spec)
    if spec.name == "disc" and (given.get("h") is not None or given.get("mesh_file") is not None):
        return ["--sweep runs the named --level meshes: drop --h/--mesh (or inspect one mesh at a time)"]
    args.sweep = args.sweep or list(default_values)
    errors = []
    choices = spec.param(param).choices           # (values() checks the choices of strings only)
    for v in args.sweep:
        if choices is not None and v not in choices:
            errors.append(f"--sweep {v}: --{spec.param(param).option} must be one of {', '.join(map(str, choices))}")
            continue
        try:
            values = spec.values({**given, param: v}, cli=True)
            errors += [f"--sweep {v}: {m}" for m in _memory(spec, values, args.pair)]
        except ProblemInputError as e:
            errors.append(f"--sweep {v}: {e}")
    return errors


def _memory(spec, values, pairs):
    """A message when the inspection would need more memory than the machine has."""
    try:
        check_memory(spec, values, [q for q in pairs if q in PAIRS], MPI.COMM_WORLD, cli=True, inspect=True)
    except RunInputError as e:
        return [str(e)]
    return []


def main(argv=None):
    """``python -m sdm_dolfinx inspect ...``: returns the exit status (0, 1 failed measurement, 2 bad input)."""
    comm = MPI.COMM_WORLD
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        try:
            spec = choose_spec(argv, comm)
        except UsageError:
            if "-h" not in argv and "--help" not in argv:
                raise
            spec = problems.get(DEFAULT_PROBLEM)         # --help of an unknown problem: the default's
        args = parse_or_help(build_parser(spec), argv, comm)
        if args is None:
            return 0
        given = check(args, spec)
    except UsageError as e:
        return report_usage_error(PROG, e, comm)
    try:
        rows = measure_all(spec, given, args, comm)
    except InspectError as e:
        return say_error(PROG, e, comm, 1)
    except (MeshError, ProblemInputError, DiscretisationError) as e:   # a --mesh file that cannot be used,
        return say_error(PROG, e, comm, 2)                              # friction on a scalar problem: bad input
    if comm.rank == 0:
        write_outputs(rows, spec, args, argv, comm)
    return 0


def measure_all(spec, given, args, comm):
    """The result rows: every pair on the one mesh, or every pair on every mesh of the sweep
    (printed as they come, on rank 0)."""
    def say(text):
        if comm.rank == 0:
            print(text, flush=True)

    def make_problem(value=None):
        values = dict(given) if value is None else {**given, _sweep_of(spec)[0]: value}
        return spec.problem(comm, **values)

    if args.skipped:
        say(f"--constrain nodes: skipped {', '.join(args.skipped)} (W^h has no dof on the constrained boundary "
            f"but at the vertices: the same as --constrain vertices)")
    if args.sweep is None:
        problem = make_problem()
        rows = []
        for pair in args.pair:
            rows.append(inspect(problem, pair, tol=args.tol, dense_max=args.dense_max, constrain=args.constrain))
            say(report(rows[-1]))
            if args.coulomb_bound:
                rows[-1]["coulomb_bound"] = coulomb_bound(problem, pair, args.dt, args.scheme)
                say(bound_line(rows[-1]["coulomb_bound"]))
        return rows
    param = _sweep_of(spec)[0]
    say(f"sweep of {spec.name} over --{param} = {' '.join(map(str, args.sweep))} on {comm.size} rank(s); "
        f"beta of condition (7), tolerance {args.tol:.1e}")
    say(SWEEP_HEADER.replace("param", param))
    return sweep(make_problem, args.sweep, args.pair, tol=args.tol, dense_max=args.dense_max,
                 progress=lambda r: say(sweep_line(r)), constrain=args.constrain)


def write_outputs(rows, spec, args, argv, comm):
    """The plot of a sweep and the JSON file (rank 0)."""
    if args.sweep is not None:
        args.png.parent.mkdir(parents=True, exist_ok=True)
        plot_sweep(rows, args.png, title=f"{spec.name}: inf-sup constant of condition (7)")
        print(f"wrote {args.png}", flush=True)
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        doc = {"command": " ".join([PROG] + argv), "ranks": comm.size, "tolerance": args.tol,
               "constrain": args.constrain, "skipped": args.skipped,
               "dense_max": args.dense_max, "versions": compat.versions(), "results": rows}
        atomic_write_text(args.json, json_text(doc, indent=1))
        print(f"wrote {args.json}", flush=True)
