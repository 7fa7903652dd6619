"""The run folder's guard: never overwrite a run by accident, refuse an unwritable folder or
one another process is running in (:class:`FolderLock`), and read back what a run recorded
(``run.json``)."""
import errno
import fcntl
import json
import os
import socket
import tempfile
import time
from pathlib import Path
from typing import Any, Optional, Union

from mpi4py import MPI

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.mpiutil import on_rank0
from sdm_dolfinx.io.checkpoint import CheckpointError

#: the lock file of a run folder (rank 0 holds an advisory lock on it for the run's life)
LOCK = ".lock"
#: bytes the lock file keeps in reserve: released on a full disc so that run.json can still
#: say "failed"
RESERVE = 64 * 1024


class RunFolderError(SdmError, RuntimeError):
    """The output folder cannot take this run (one line, nothing written)."""


class FolderInUseError(RunFolderError, CheckpointError):
    """Another process is running in the folder (one line, nothing written).

    Also a CheckpointError only so that the command line's existing one-line mapping of
    that error (exit status 2) applies to it."""


def read_info(folder: Union[str, Path], comm: MPI.Comm = MPI.COMM_WORLD) -> dict[str, Any]:
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


def check_out(out: Path, overwrite: bool, comm: MPI.Comm = MPI.COMM_WORLD) -> Optional[str]:
    """The output folder must be writable and must not hold a run (unless ``overwrite``).

    Returns:
        the run id of the run.json seen (None: none), for :func:`same_run_as_checked` once
        the run holds the folder's lock (another process may have started in between).

    Raises:
        RunFolderError: on every rank, with the reason and what to do.
    """
    on_rank0(comm, _check_out, Path(out), overwrite, wrap=RunFolderError)
    return on_rank0(comm, _run_id, Path(out), wrap=RunFolderError)


def _run_id(out):
    try:
        data = json.loads((out / "run.json").read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError, UnicodeDecodeError):
        return "unreadable"
    return data.get("run_id", "unknown") if isinstance(data, dict) else "unknown"


def same_run_as_checked(out, seen, comm=MPI.COMM_WORLD):
    """Under the folder's lock: the folder must still hold what :func:`check_out` saw (the
    check and the lock are two steps: a run started between them must not be overwritten)."""
    now = on_rank0(comm, _run_id, Path(out), wrap=RunFolderError)
    if now != seen:
        raise RunFolderError(f"{out} was written by another run since this one was checked (run id {now}); "
                             f"use --overwrite or another --out")


def _check_out(out, overwrite):
    holder = lock_holder(out)
    if holder is not None:
        raise FolderInUseError(f"{out} is in use by another run ({holder}); wait for it to end or choose "
                               f"another --out")
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


def lock_holder(folder):
    """Who holds ``folder``'s lock ("pid N on HOST since ..."), or None when nobody does (no lock
    file, or a stale one: the lock dies with its process). Not collective."""
    path = Path(folder) / LOCK
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _describe_holder(fd)
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def _describe_holder(fd):
    try:
        line = os.pread(fd, 200, 0).split(b"\n", 1)[0].decode("utf-8", "replace").strip()
    except OSError:
        line = ""
    return line or "a process that did not say who it is"


class FolderLock:
    """An advisory lock (``flock``) on ``folder/.lock``, held by rank 0 for a run's life
    (collective). A second run, or a restart, in the same folder is refused; a lock left by
    a dead process is no lock (flock dies with its process). The file also keeps
    :data:`RESERVE` bytes, released by :meth:`free_reserve` when the disc is full.

    Raises:
        FolderInUseError: another live process holds it (after ``wait`` seconds).
        OSError: the folder or the lock file cannot be created (on every rank: as
            RunFolderError).
    """

    def __init__(self, folder, comm=MPI.COMM_WORLD, wait=1.0):
        self.folder, self.comm, self.fd = Path(folder), comm, None
        err = None
        if comm.rank == 0:
            try:
                self._acquire(wait)
            except FolderInUseError as e:
                err = ("busy", str(e))
            except OSError as e:
                err = ("os", f"cannot create the lock file {self.folder / LOCK}: {e.strerror or e}")
        err = comm.bcast(err, root=0)
        if err is not None:
            raise (FolderInUseError if err[0] == "busy" else RunFolderError)(err[1])

    def _acquire(self, wait):
        self.folder.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.folder / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        deadline = time.monotonic() + wait
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:      # (a brief wait: check_out's probe holds it a moment)
                    holder = _describe_holder(fd)
                    os.close(fd)
                    raise FolderInUseError(f"{self.folder} is in use by another run ({holder}); wait for it "
                                           f"to end or choose another --out") from None
                time.sleep(0.05)
        self.fd = fd
        head = (f"pid {os.getpid()} on {socket.gethostname()} since "
                f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n").encode()
        self._head = len(head)
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, head, 0)
            os.posix_fallocate(fd, 0, RESERVE)
        except OSError as e:
            if e.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EOPNOTSUPP, errno.EINVAL):
                raise
            # no room for the reserve: the run finds out at its first write

    def free_reserve(self):
        """Give the reserved bytes back to the file system (rank 0; not collective)."""
        if self.fd is not None:
            try:
                os.ftruncate(self.fd, self._head)
            except OSError:
                pass

    def release(self):
        """Unlock (the file stays: a stale lock file is harmless). Not collective."""
        if self.fd is not None:
            self.free_reserve()
            try:
                fcntl.flock(self.fd, fcntl.LOCK_UN)
            finally:
                os.close(self.fd)
                self.fd = None
