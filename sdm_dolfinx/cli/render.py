"""``python -m sdm_dolfinx render RUN_DIR [--png F] [--gif F] [--time T] [--merge]``: pictures
of a run from its files (pyvista off-screen when installed, else matplotlib) and a
ParaView-friendly merged XDMF. Works on any run folder, a problem file's included."""
import sys
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx.cli.common import Parser, UsageError, check_writable, parse_or_help, report_usage_error

PROG = "python -m sdm_dolfinx render"


def build_parser():
    p = Parser(prog=PROG, description="Pictures of a run from its solution.xdmf (pyvista if installed, else "
                                      "matplotlib), and a ParaView-friendly merged XDMF.")
    p.add_argument("run", type=Path, help="the run's folder (or its solution.xdmf)")
    p.add_argument("--png", type=Path, help="write a picture at --time (default: the last output time)")
    p.add_argument("--gif", type=Path, help="write an animation of all output times (.gif, or .mp4)")
    p.add_argument("--time", type=float, default=None, help="time of the picture (nearest output time)")
    p.add_argument("--scale", type=float, default=None,
                   help="displacement magnification (default 10 for the membrane, 1 for elastic bodies)")
    p.add_argument("--every", type=int, default=1, metavar="K", help="animation: every K-th output time")
    p.add_argument("--size", type=int, nargs=2, default=None, metavar=("W", "H"), help="picture size in pixels")
    p.add_argument("--fps", type=float, default=12, help="animation frames per second (default 12)")
    p.add_argument("--merge", action="store_true",
                   help="write solution_paraview.xdmf: all fields in one temporal grid (for ParaView)")
    return p


def _check(args):
    src = args.run / "solution.xdmf" if args.run.is_dir() else args.run
    if not src.is_file():
        raise UsageError(f"{args.run}: no solution.xdmf there (a run folder written with --out)")
    if not (args.png or args.gif or args.merge):
        raise UsageError("nothing to do: give --png, --gif or --merge")
    if args.every < 1 or args.fps <= 0 or (args.size and min(args.size) < 16):
        raise UsageError("--every must be >= 1, --fps > 0 and --size at least 16 16")
    for path, what in ((args.png, "--png"), (args.gif, "--gif")):
        if path is not None:
            check_writable(path, what)
    return src


def main(argv=None, comm=MPI.COMM_WORLD):
    """The render command (rank 0 draws); returns the exit status."""
    from sdm_dolfinx.post import render
    parser = build_parser()
    try:
        args = parse_or_help(parser, list(argv or []), comm)
        if args is None:
            return 0
        src = _check(args)
    except UsageError as e:
        return report_usage_error(PROG, e, comm)
    if comm.rank != 0:
        return 0
    if args.merge:
        print(f"wrote {render.merge_xdmf(src)}")
    if args.png or args.gif:
        series = render.read_xdmf(src)
        if series.cell_type in ("PolyLine", "Edge_3"):
            print(f"{PROG}: error: {src} is a 1-D run: render draws 2-D and membrane runs; plot u(x, t) from its "
                  f"time series, or open solution.xdmf in ParaView (Plot Over Line)", file=sys.stderr)
            return 2
        if args.png:
            how = render.picture(series, args.png, time=args.time, scale=args.scale, size=args.size or (900, 700))
            print(f"wrote {args.png} ({how})")
        if args.gif:
            how = render.animation(series, args.gif, times=series.times[::args.every], scale=args.scale,
                                   size=args.size or (640, 640), fps=args.fps)
            print(f"wrote {args.gif} ({how})")
    return 0
