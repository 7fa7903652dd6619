"""What every command shares: one-line usage errors (exit 2), --help on rank 0, internal
errors that take every rank down, and argparse types."""
import argparse
import math
import os
import re
import sys

from sdm_dolfinx.errors import SdmError

#: argparse reads "-6e-1" as an option: numbers in exponent notation count as numbers too
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


class UsageError(SdmError):
    """Bad input: reported in one line with exit status 2."""


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors raise UsageError (one line, status 2) instead of exiting,
    and which takes negative numbers in any notation as values."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message):
        raise UsageError(f"{self.prog}: error: {message}")


def parse_or_help(parser, argv, comm):
    """A command's arguments, or None after printing its ``--help`` (on rank 0).

    Raises:
        UsageError: bad arguments (``parser`` is a :class:`Parser`).
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


def say_error(prog, message, comm, status):
    """Print ``prog: error: message`` on rank 0's stderr; returns ``status``."""
    if comm.rank == 0:
        print(f"{prog}: error: {message}", file=sys.stderr, flush=True)
    return status


def internal_error(prog, e, comm):
    """An unexpected exception: say it in one line (SDM_DEBUG=1 shows the traceback) and take
    every rank down (no deadlock when one rank fails alone); returns exit status 1."""
    print(f"{prog}: internal error on rank {comm.rank}: {type(e).__name__}: {e}", file=sys.stderr, flush=True)
    if os.environ.get("SDM_DEBUG"):
        raise e
    if comm.size > 1:
        comm.Abort(1)
    return 1


def positive_float(text):
    """argparse type: a finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive finite number (got {text})")
    return v


def nonnegative_float(text):
    """argparse type: a finite number >= 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0 (got {text})")
    return v


def positive_int(text):
    """argparse type: an integer >= 1."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1 (got {v})")
    return v


def folder_path(text):
    """argparse type: a folder's path, not empty (``Path("")`` would be the current folder)."""
    if not str(text).strip():
        raise argparse.ArgumentTypeError("empty: name a folder (. for the current one)")
    from pathlib import Path
    return Path(text)


#: the files of a run folder (docs/outputs.md) that no command writes but the run (and energy its own)
RUN_FOLDER_FILES = ("run.json", "timeseries.csv", "solution.xdmf", "solution.h5", "state.h5", "checkpoint.npz",
                    "obstacles.xdmf", "energy_recomputed.csv", ".lock")


def check_writable(path, what):
    """A file the command will write: not a folder, not a file of a run folder (nor any file of
    one a run is writing now), and its nearest existing folder writable (tried with a temporary
    file: ``os.access`` says yes to root on /proc or a read-only mount)."""
    import tempfile
    from sdm_dolfinx.io.folder import lock_holder
    if path.exists() and path.is_dir():
        raise UsageError(f"{what} {path} is a folder")
    folder = path.parent
    holder = lock_holder(folder) if folder.is_dir() else None
    if holder is not None and path.name in RUN_FOLDER_FILES:
        raise UsageError(f"{what} {path}: {folder} holds a run in progress ({holder}): choose another file")
    if path.name in RUN_FOLDER_FILES and (folder / "run.json").is_file():
        raise UsageError(f"{what} {path} is the {path.name} of the run in {folder}: choose another file")
    d = folder
    while not d.exists():
        d = d.parent
    if not os.access(d, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write {what} {path} ({d} is not writable)")
    try:
        with tempfile.TemporaryFile(dir=d):
            pass
    except OSError as e:
        raise UsageError(f"cannot write {what} {path} (creating a file in {d} failed: {e.strerror or e})") from None


def check_finished_run(folder, comm, files, doing):
    """UsageError (one line) unless ``folder`` holds a finished run's ``files``: a run still writing
    them (its lock held) is refused too, ``doing`` saying what waits for its end (collective)."""
    from sdm_dolfinx.io.folder import lock_holder
    holder = comm.bcast(lock_holder(folder) if comm.rank == 0 else None, root=0)
    if holder is not None:          # its files are being written: state.h5 may be mid-write
        raise UsageError(f"{folder} holds a run in progress ({holder}): wait for it to end, then {doing}")
    for name in files:
        if not (folder / name).exists():
            raise UsageError(f"{folder} has no {name} (not the output folder of a run)")


def parse_run_folder(prog, parser, argv, comm, files, doing, check_folder):
    """A command on a finished run's folder (``energy``, ``vtx``): its parsed arguments (``args.folder``)
    once :func:`check_finished_run` and ``check_folder(folder)`` (rank 0) have passed, or the exit
    status to return: 0 after ``--help``, 2 after a one-line refusal (collective)."""
    from sdm_dolfinx.mpiutil import on_rank0
    try:
        args = parse_or_help(parser, argv, comm)
        if args is None:
            return 0
        check_finished_run(args.folder, comm, files, doing)
        on_rank0(comm, check_folder, args.folder, wrap=UsageError)
    except UsageError as e:
        return report_usage_error(prog, e, comm)
    return args
