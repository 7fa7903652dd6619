"""``python -m sdm_dolfinx render RUN_DIR [--png F] [--gif F] [--time T] [--merge]``: pictures
of a run from its files (pyvista off-screen when installed, else matplotlib) and a
ParaView-friendly merged XDMF. Works on any 2-D or 3-D run folder, a problem file's included.
Bad input (a time outside the run's, a scale that is not a finite positive number, a file name
of another format, an option that would do nothing, a folder that cannot be written) is
refused in one line before anything is written."""
import sys
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx.cli.common import (Parser, UsageError, check_writable, parse_or_help, positive_float, positive_int,
                                    report_usage_error)
from sdm_dolfinx.mpiutil import on_rank0

PROG = "python -m sdm_dolfinx render"
#: picture sizes accepted (pixels per side)
SIZES = (16, 8192)


def build_parser():
    p = Parser(prog=PROG, description="Pictures of a run from its solution.xdmf (pyvista if installed, else "
                                      "matplotlib), with the obstacle its problem declares, and a ParaView-friendly "
                                      "merged XDMF.")
    p.add_argument("run", type=Path, help="the run's folder (or its solution.xdmf)")
    p.add_argument("--png", type=Path, help="write a picture (.png) at --time (default: the last output time)")
    p.add_argument("--gif", type=Path, help="write an animation of the output times (.gif, or .mp4)")
    p.add_argument("--time", type=float, default=None,
                   help="time of the picture: the nearest output time (within the run's output times)")
    p.add_argument("--scale", type=float, default=None,
                   help="displacement magnification, > 0 (default 10 for the membrane, 1 for elastic bodies)")
    p.add_argument("--every", type=positive_int, default=None, metavar="K",
                   help="animation: every K-th output time (default 1)")
    p.add_argument("--size", type=int, nargs=2, default=None, metavar=("W", "H"),
                   help=f"picture size in pixels, {SIZES[0]} to {SIZES[1]} (default 900 700, animations 640 640; a 3-D "
                        f"body, in two views: 1200 600 and 960 480)")
    p.add_argument("--fps", type=positive_float, default=None, help="animation frames per second (default 12)")
    p.add_argument("--merge", action="store_true",
                   help="write solution_paraview.xdmf: all fields in one temporal grid (for ParaView)")
    return p


def _check_args(args):
    """What the command line alone says (every rank)."""
    if not (args.png or args.gif or args.merge):
        raise UsageError("nothing to do: give --png, --gif or --merge")
    unused = [name for name, value, needs in (("--time", args.time, args.png), ("--every", args.every, args.gif),
                                              ("--fps", args.fps, args.gif),
                                              ("--scale", args.scale, args.png or args.gif),
                                              ("--size", args.size, args.png or args.gif)) if value is not None and not needs]
    if unused:
        what = "--png" if unused[0] == "--time" else "--gif" if unused[0] in ("--every", "--fps") else "--png or --gif"
        raise UsageError(f"{unused[0]} is used by {what}, which is not given")
    if args.size and not all(SIZES[0] <= s <= SIZES[1] for s in args.size):
        raise UsageError(f"--size {args.size[0]} {args.size[1]}: each side from {SIZES[0]} to {SIZES[1]} pixels")


def _check_files(args):
    """What the run's files say (rank 0): the XDMF readable and drawable, the time and scale
    within what it holds, the outputs' formats and folders. Returns (source, series or None)."""
    from sdm_dolfinx.post import render
    src = args.run / "solution.xdmf" if args.run.is_dir() else args.run
    if not src.is_file():
        raise UsageError(f"{args.run}: no solution.xdmf there (a run folder written with --out)")
    series = None
    try:
        if args.png or args.gif:
            series = render.read_xdmf(src)
            render.check_scale(render.kind_of(series), args.scale)
            if args.png:
                render.check_time(series, args.time)
                render.check_output(args.png, (".png",))
            if args.gif:
                render.check_output(args.gif, (".gif", ".mp4"))
    except render.RenderError as e:
        raise UsageError(str(e)) from None
    for path, what in ((args.png, "--png"), (args.gif, "--gif"), (render.merged_path(src) if args.merge else None,
                                                                   "--merge")):
        if path is not None:
            check_writable(path, what)
    return src, series


def main(argv=None, comm=MPI.COMM_WORLD):
    """The render command (rank 0 draws); returns the exit status."""
    from sdm_dolfinx.post import render
    parser = build_parser()
    try:
        args = parse_or_help(parser, list(argv or []), comm)
        if args is None:
            return 0
        _check_args(args)
        checked = {}
        on_rank0(comm, lambda: checked.update(zip(("src", "series"), _check_files(args))), wrap=UsageError)
    except UsageError as e:
        return report_usage_error(PROG, e, comm)
    if comm.rank != 0:
        return 0
    src, series = checked["src"], checked["series"]
    if series is not None:               # built before anything is written (a warning if unknown)
        if args.png:
            render.obstacle_of(series, render.check_time(series, args.time), scale=args.scale)
        if args.gif:
            render.obstacle_of(series, times=series.times[::args.every or 1], scale=args.scale)
    if args.merge:
        print(f"wrote {render.merge_xdmf(src)}")
    if args.png:
        how = render.picture(series, args.png, time=args.time, scale=args.scale, size=args.size)
        print(f"wrote {args.png} (t = {render.check_time(series, args.time):g}, {how})")
    if args.gif:
        times = series.times[::args.every or 1]
        how = render.animation(series, args.gif, times=times, scale=args.scale, size=args.size,
                               fps=args.fps or 12)
        print(f"wrote {args.gif} ({len(times)} frames, {how})")
    sys.stdout.flush()
    return 0
