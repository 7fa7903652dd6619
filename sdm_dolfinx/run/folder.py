"""The run folder's guard: never overwrite a run by accident, refuse an unwritable folder,
and read back what a run recorded (``run.json``)."""
import json
import os
import tempfile
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx.mpiutil import on_rank0


class RunFolderError(RuntimeError):
    """The output folder cannot take this run (one line, nothing written)."""


def read_info(folder, comm=MPI.COMM_WORLD):
    """``folder/run.json`` as a dict on every rank; RunFolderError when missing or unreadable."""
    def read():
        path = Path(folder) / "run.json"
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            raise RunFolderError(f"{folder}: no run.json there") from None
        except (OSError, ValueError, UnicodeDecodeError) as e:
            raise RunFolderError(f"{path}: cannot read it ({e})") from None
        if not isinstance(data, dict):
            raise RunFolderError(f"{path}: not a run description (a JSON object)")
        return data
    return on_rank0(comm, read, wrap=RunFolderError)


def check_out(out, overwrite, comm=MPI.COMM_WORLD):
    """The output folder must be writable and must not hold a run (unless ``overwrite``).

    Raises:
        RunFolderError: on every rank, with the reason and what to do.
    """
    return on_rank0(comm, _check_out, Path(out), overwrite, wrap=RunFolderError)


def _check_out(out, overwrite):
    run = out / "run.json"
    if run.exists() and not overwrite:
        try:
            status = json.loads(run.read_text()).get("status")
        except (OSError, ValueError, AttributeError, UnicodeDecodeError):
            status = "unreadable"
        if status == "finished":
            raise RunFolderError(f"{out} already holds a finished run; use --overwrite or another --out")
        if status == "failed":
            raise RunFolderError(f"{out} holds a failed run (see its run.json); use --overwrite or another --out")
        if status == "interrupted":
            raise RunFolderError(f"{out} holds an interrupted run; continue it with --restart {out}, "
                                 f"or use --overwrite")
        has = (out / "checkpoint.npz").exists()
        what = "a run that is still going or was killed" if status == "running" else f"a run.json ({status})"
        raise RunFolderError(f"{out} holds {what}" + (f"; continue it with --restart {out}" if has else "")
                             + ", or use --overwrite")
    if out.exists() and not out.is_dir():
        raise RunFolderError(f"--out {out} exists and is not a folder")
    probe_dir = out
    while not probe_dir.exists():
        probe_dir = probe_dir.parent
    if not probe_dir.is_dir() or not os.access(probe_dir, os.W_OK | os.X_OK):
        raise RunFolderError(f"cannot write to {out} ({probe_dir} is not a writable folder)")
    # os.access says yes to root on a read-only file system (/proc, a read-only mount): try
    # a temporary file in the folder that exists (removed at once: nothing is left behind)
    try:
        with tempfile.TemporaryFile(dir=probe_dir):
            pass
    except OSError as e:
        raise RunFolderError(f"cannot write to {out} (creating a file in {probe_dir} failed: "
                             f"{e.strerror or e})") from None
