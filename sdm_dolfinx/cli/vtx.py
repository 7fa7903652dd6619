"""``python -m sdm_dolfinx vtx DIR``: a finished run's displacement and velocity as VTX files
(``DIR/vtx/displacement.bp``, ``velocity.bp``; :func:`sdm_dolfinx.post.vtx.export_vtx`), each field in
its own finite element space, for ParaView's ADIOS2 reader. Needs a dolfinx built with ADIOS2 (PyPI's
wheel dolfinx-solver-real; not Debian 12's 0.5.2).

Bad input (not a run folder, a run in progress, no ADIOS2, a problem that cannot be rebuilt): one
line, exit status 2.
"""
import sys
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx.cli.common import Parser, UsageError, parse_run_folder, say_error
from sdm_dolfinx.io import PostprocessError
from sdm_dolfinx.post.vtx import VTX_FOLDER, export_vtx

PROG = "python -m sdm_dolfinx vtx"
#: the files a run folder must hold
RUN_FILES = ("run.json", "state.h5")


def build_parser():
    p = Parser(prog=PROG, description="Write a finished run's displacement and velocity at every state of its "
               "state.h5 as VTX files (ADIOS2), DIR/vtx/displacement.bp and DIR/vtx/velocity.bp, each field in its "
               "own finite element space (P2 at its dofs; P1+ exactly as P3 or P4; the velocity P0 per cell), "
               "for ParaView's ADIOS2VTXReader. Needs dolfinx built with ADIOS2 (PyPI's wheel "
               "dolfinx-solver-real has it; Debian 12's 0.5.2 does not).")
    p.add_argument("folder", type=Path, metavar="DIR", help="a run's output folder")
    return p


def check_folder(folder):
    """DIR/vtx can be written (a file of that name, or a folder where no file can be made, is refused;
    earlier VTX files there are replaced)."""
    import tempfile
    out = folder / VTX_FOLDER
    if out.exists() and not out.is_dir():
        raise UsageError(f"{out} is a file: the VTX files go into a folder of that name")
    try:
        with tempfile.TemporaryFile(dir=out if out.is_dir() else folder):
            pass
    except OSError as e:
        raise UsageError(f"cannot write the VTX files into {out} ({e.strerror or e})") from None


def main(argv=None):
    """``python -m sdm_dolfinx vtx DIR``: returns the exit status (0, 2 bad input)."""
    comm = MPI.COMM_WORLD
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_run_folder(PROG, build_parser(), argv, comm, RUN_FILES, "write its VTX files", check_folder)
    if isinstance(args, int):
        return args
    try:
        paths, steps = export_vtx(args.folder, comm)
    except PostprocessError as e:
        return say_error(PROG, e, comm, 2)
    if comm.rank == 0:
        print(f"{args.folder}: {steps} stored states -> {', '.join(str(p) for p in paths)}", flush=True)
    return 0
