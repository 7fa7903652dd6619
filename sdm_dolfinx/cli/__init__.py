"""The command line: ``python -m sdm_dolfinx COMMAND [options]``.

Commands: one per registered problem (a run: :mod:`.run`), ``run`` for a problem file, and
the tools ``energy``, ``inspect``, ``figures``, ``render`` and ``compare``. Each command's module does its argparse
and one-line error handling; nothing in the package imports this layer.
"""
import argparse
import contextlib
import importlib
import sys

from mpi4py import MPI

from sdm_dolfinx import problems
from sdm_dolfinx.cli.common import Parser, internal_error

PROG = "python -m sdm_dolfinx"
#: commands that are not a run: name -> (module with ``main(argv) -> status``, one-line help)
TOOLS = {
    "inspect": ("sdm_dolfinx.cli.inspect", "measure the inf-sup condition (7) of a problem, pair and mesh "
                                           "(well-posedness)"),
    "figures": ("sdm_dolfinx.cli.figures", "rerun the paper's studies (only what is missing) and regenerate its "
                                           "figures and Table 2"),
    "energy": ("sdm_dolfinx.cli.energy", "recompute a finished run's energy history from its state.h5"),
    "vtx": ("sdm_dolfinx.cli.vtx", "a finished run's fields as VTX (ADIOS2) files, each in its own finite element "
                                   "space (needs dolfinx with ADIOS2)"),
    "render": ("sdm_dolfinx.cli.render", "pictures and animations of a run from its files; ParaView-friendly XDMF"),
    "compare": ("sdm_dolfinx.cli.compare", "compare dynamic-contact methods on one problem over a grid of h and dt "
                                           "(metrics against the exact solution, figures, ranking)"),
}


class _CommandsFormatter(argparse.HelpFormatter):
    """Room for every command's name before its help: argparse leaves the commands' own indent out of the
    width it measures, so a name of 9 letters (two_balls) would go on a line of its own."""

    def add_argument(self, action):
        super().add_argument(action)
        names = [len(a.dest) for a in self._iter_indented_subactions(action)] if action.help != argparse.SUPPRESS \
            else []
        self._action_max_length = max([self._action_max_length] + [n + self._current_indent + 4 for n in names])


def top_parser():
    """The top-level parser, for ``--help``: it names every command with its one-line help
    (each command parses its own options)."""
    parser = Parser(prog=PROG, description="The singular dynamic method for dynamic contact (Renard 2010) on dolfinx.",
                    epilog=f"`{PROG} COMMAND --help` lists the options of a command.",
                    formatter_class=_CommandsFormatter)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for name in problems.names(builtin=True):
        sub.add_parser(name, help="run: " + problems.get(name).summary, add_help=False)
    sub.add_parser("run", help="run a problem of your own: run --problem-file FILE (docs/add_a_problem.md)",
                   add_help=False)
    for name, (_, text) in TOOLS.items():
        sub.add_parser(name, help=text, add_help=False)
    return parser


def commands():
    """Every command's name."""
    return [*problems.names(builtin=True), "run", *TOOLS]


@contextlib.contextmanager
def _one_line_warnings():
    """While a command runs, warnings (e.g. the boundary-gap warning) read ``warning: message``
    on stderr; Python's own format is restored afterwards."""
    import warnings
    saved = warnings.formatwarning
    warnings.formatwarning = lambda message, category, *args, **kwargs: f"warning: {message}\n"
    try:
        yield
    finally:
        warnings.formatwarning = saved


def main(argv=None):
    """Entry point; returns the exit status (0 ok, 1 failed run, 2 bad input, 128+sig interrupted)."""
    comm = MPI.COMM_WORLD
    with _one_line_warnings():
        return _main(argv, comm)


def _main(argv, comm):
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] in ("-h", "--help"):
        if comm.rank == 0:
            top_parser().print_help(sys.stdout if argv else sys.stderr)
        return 0 if argv else 2
    command, rest = argv[0], argv[1:]
    try:
        if command in TOOLS:
            return importlib.import_module(TOOLS[command][0]).main(rest)
        if command == "run" or command in problems.names(builtin=True):
            from sdm_dolfinx.cli import run
            return run.main(command, rest, comm)
    except KeyboardInterrupt:           # Ctrl-C before the run's own handlers (imports, set-up)
        if comm.rank == 0:
            print(f"{PROG} {command}: interrupted before the run started (nothing written)", file=sys.stderr,
                  flush=True)
        return 130
    except Exception as e:
        return internal_error(f"{PROG} {command}", e, comm)
    if comm.rank == 0:
        print(f"{PROG}: error: unknown command {command!r}; choose one of {', '.join(commands())}",
              file=sys.stderr, flush=True)
    return 2
