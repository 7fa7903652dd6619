"""Crash-safe HDF5 files: an undo log of the bytes overwritten since the last checkpoint.

HDF5 updates its metadata in place, so a run killed (or out of disc space) while writing
``solution.h5`` or ``state.h5`` can leave the whole file unreadable, every earlier step
included. Both files are therefore written through :class:`JournaledFile` (rank 0, h5py's
file-object driver), which

* before overwriting a byte below the file's *committed* size (its size at the last
  checkpoint), appends the old bytes to an undo log beside it (``.solution.h5.undo``); a
  restart applies the log backwards and cuts the file to its committed size
  (:func:`rollback`), which is exactly the file of the checkpoint, whatever the moment of
  the kill (the log entry is written before the bytes it saves are overwritten);
* keeps, for one opening of the file (a *session*: one output step), the old bytes of
  everything it overwrites in memory: a failed session (no space left, an interrupt) is
  undone at once, and the file is left as it was before that step.

A commit (:meth:`JournaledFile.commit`, at each checkpoint) starts a new, empty log named
by the checkpoint's token; a log whose token is not the checkpoint's is ignored (a kill
between writing the checkpoint and starting the new log: the files are the checkpoint's).
Protects against the process dying, not the machine: nothing is fsync'ed.

Rank 0 only; imports nothing of the package.
"""
import errno
import io
import os
import struct
from contextlib import contextmanager
from pathlib import Path

from sdm_dolfinx.errors import SdmError

MAGIC = b"SDMUNDO1"
_HEAD = struct.Struct("<8sQ32s")        # magic, committed size, token (32 ASCII characters)
_ENTRY = struct.Struct("<QQ")           # offset, length of the saved bytes that follow


class FileVanished(SdmError, OSError):
    """A run's file was deleted or replaced by someone else while the run was writing it."""

    def __init__(self, path):
        super().__init__(errno.ENOENT, "deleted or replaced during the run", str(path))


def undo_path(path):
    """The undo log of ``path``: ``.NAME.undo`` beside it."""
    path = Path(path)
    return path.with_name(f".{path.name}.undo")


def start_log(path, token, size):
    """Replace ``path``'s undo log by an empty one for the commit ``token`` at ``size`` bytes
    (atomically: a kill leaves the old log or the new one)."""
    log = undo_path(path)
    tmp = log.with_name(log.name + ".tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(_HEAD.pack(MAGIC, int(size), token.encode("ascii")[:32].ljust(32)))
        os.replace(tmp, log)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def read_log(path):
    """(token, committed size, [(offset, bytes), ...]) of ``path``'s undo log, or None when it
    is missing or has no valid header. A torn last entry (the write that followed it never
    happened) is left out."""
    try:
        data = undo_path(path).read_bytes()
    except OSError:
        return None
    if len(data) < _HEAD.size:
        return None
    magic, size, token = _HEAD.unpack_from(data)
    if magic != MAGIC:
        return None
    entries, pos = [], _HEAD.size
    while pos + _ENTRY.size <= len(data):
        off, n = _ENTRY.unpack_from(data, pos)
        if pos + _ENTRY.size + n > len(data):
            break
        entries.append((off, data[pos + _ENTRY.size:pos + _ENTRY.size + n]))
        pos += _ENTRY.size + n
    return token.decode("ascii").strip(), size, entries


def rollback(path, token, size):
    """Bring ``path`` back to the state of the commit ``token`` (``size`` bytes): apply its
    undo log newest entry first and cut it to ``size``. Idempotent (a restart killed while
    doing it does it again). Returns "missing" (no file), "short" (the file is shorter than
    its committed size: damaged by something else) or "ok"."""
    path = Path(path)
    if not path.exists():
        return "missing"
    log = read_log(path)
    fd = os.open(path, os.O_RDWR)
    try:
        if log is not None and log[0] == token:
            for off, old in reversed(log[2]):
                _pwrite_all(fd, old, off)
        if os.fstat(fd).st_size < size:
            return "short"
        os.ftruncate(fd, size)
    finally:
        os.close(fd)
    return "ok"


def _pwrite_all(fd, data, off):
    view = memoryview(data)
    while len(view):
        n = os.pwrite(fd, view, off)
        view, off = view[n:], off + n


class JournaledFile:
    """One HDF5 file of a run, written through :meth:`h5` only (rank 0).

    Args:
        path: the file.
        committed: its size at the last commit (0: nothing to protect yet).
        token: that commit's token (its undo log's name for it).
    """

    def __init__(self, path, committed=0, token=None):
        self.path, self.committed, self.token = Path(path), int(committed), token
        self._logged = set()            # (offset, end) ranges saved in the log since the commit
        self._log, self._log_len = None, 0
        self._inode = None
        self._last = None               # (size before, [(offset, old bytes)]) of the last session since the commit
        if self.path.exists():
            self._inode = os.stat(self.path).st_ino

    @contextmanager
    def h5(self, mode="r+"):
        """``with jf.h5() as h5:`` an ``h5py.File`` on the file (``mode="w"``: create it);
        undone and the error raised again if anything fails before it is closed.

        Raises:
            FileVanished: the file was deleted or replaced since the last session.
            OSError: the write failed (errno ENOSPC: no space left).
        """
        import h5py
        create = mode == "w"
        if not create:
            try:
                inode = os.stat(self.path).st_ino
            except FileNotFoundError:
                raise FileVanished(self.path) from None
            if self._inode is not None and inode != self._inode:
                raise FileVanished(self.path)
        io_ = _UndoIO(self, create)
        try:
            self._inode = os.fstat(io_.fd).st_ino
            try:
                f = h5py.File(io_, mode)
            except BaseException:
                if io_.error is not None:
                    raise io_.error from None
                raise
            try:
                yield f
            finally:
                f.close()
            if io_.error is not None:
                raise io_.error
        except BaseException:
            io_.undo()
            raise
        finally:
            io_.release()
        self._last = (io_.size0, io_.saved)

    def undo_last(self):
        """Undo the last session (since the last commit), which went through: the file as it was
        before it (the bytes it overwrote written back, then cut to its size before). It needs no
        space, so a step whose other files could not be written (a full disc) takes its data back
        out of this one. Nothing to undo: nothing happens."""
        if self._last is None:
            return
        size0, saved = self._last
        fd = os.open(self.path, os.O_RDWR)
        try:
            for off, old in reversed(saved):
                _pwrite_all(fd, old, off)
            os.ftruncate(fd, size0)
        finally:
            os.close(fd)
        self._last = None

    def commit(self, token):
        """The file as it is now is the state of the checkpoint ``token`` (call with the file
        closed, after the checkpoint naming its size was written): its undo log starts again."""
        size = self.size()
        self.reset_log(token, size)
        self.committed, self.token = size, token
        self._last = None

    def reset_log(self, token, size):
        """Empty the undo log, then give it the header of the commit ``token`` (at a checkpoint,
        or after a restart's rollback to it): a kill in between leaves an empty log, which is
        right (the file is at that commit)."""
        if self._log is None:
            self._log = os.open(undo_path(self.path), os.O_RDWR | os.O_CREAT, 0o644)
        os.ftruncate(self._log, 0)
        self._log_len = 0
        self._logged.clear()
        head = _HEAD.pack(MAGIC, int(size), token.encode("ascii")[:32].ljust(32))
        if os.pwrite(self._log, head, 0) != len(head):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(undo_path(self.path)))
        self._log_len = len(head)

    def size(self):
        """The file's size now (FileVanished if someone deleted or replaced it)."""
        try:
            st = os.stat(self.path)
        except FileNotFoundError:
            raise FileVanished(self.path) from None
        if self._inode is not None and st.st_ino != self._inode:
            raise FileVanished(self.path)
        return st.st_size

    def close(self):
        if self._log is not None:
            os.close(self._log)
            self._log = None

    def _save(self, off, old):
        """Append the committed bytes ``old`` at ``off`` to the undo log (before they are
        overwritten)."""
        key = (off, off + len(old))
        if key in self._logged:
            return                      # the oldest copy is in the log already
        if self._log is None:           # a restart: the log restored from is continued
            self._log = os.open(undo_path(self.path), os.O_RDWR)
            self._log_len = os.fstat(self._log).st_size
        if os.fstat(self._log).st_nlink == 0:
            raise FileVanished(undo_path(self.path))
        rec = _ENTRY.pack(off, len(old)) + old
        if os.pwrite(self._log, rec, self._log_len) != len(rec):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(undo_path(self.path)))
        self._log_len += len(rec)
        self._logged.add(key)


class _UndoIO(io.RawIOBase):
    """The file object h5py writes through for one session of a :class:`JournaledFile`.

    After the first failed write it stops writing (and reports success to HDF5, which can
    then close the file cleanly); :meth:`undo` restores the file as the session found it
    and the session raises the error."""

    def __init__(self, jf, create):
        super().__init__()
        self.jf = jf
        self.fd = os.open(jf.path, os.O_RDWR | os.O_CREAT | (os.O_TRUNC if create else 0), 0o644)
        self.pos = 0
        self.size0 = os.fstat(self.fd).st_size      # the file as the session found it
        self.saved = []                              # (offset, old bytes) overwritten below size0
        self.seen = set()
        self.error = None

    def readable(self):
        return True

    def writable(self):
        return True

    def seekable(self):
        return True

    def readinto(self, b):
        data = os.pread(self.fd, len(b), self.pos)
        b[:len(data)] = data
        self.pos += len(data)
        return len(data)

    def _keep(self, off, end):
        """Save the bytes [off, end) that existed when the session started, before they change."""
        end = min(end, self.size0)
        if off >= end or (off, end) in self.seen:
            return
        old = os.pread(self.fd, end - off, off)
        self.saved.append((off, old))
        self.seen.add((off, end))
        if off < self.jf.committed:
            self.jf._save(off, old[:min(end, self.jf.committed) - off])

    def write(self, b):
        n = len(b)
        if self.error is None:
            try:
                self._keep(self.pos, self.pos + n)
                _pwrite_all(self.fd, b, self.pos)
            except BaseException as e:  # noqa: B036  (an interrupt too: undone, raised after close)
                self.error = e
        self.pos += n
        return n

    def seek(self, off, whence=io.SEEK_SET):
        if whence == io.SEEK_SET:
            self.pos = off
        elif whence == io.SEEK_CUR:
            self.pos += off
        else:
            self.pos = os.fstat(self.fd).st_size + off
        return self.pos

    def tell(self):
        return self.pos

    def truncate(self, size=None):
        size = self.pos if size is None else size
        if self.error is None:
            try:
                if size < self.size0:
                    self._keep(size, self.size0)
                os.ftruncate(self.fd, size)
            except BaseException as e:  # noqa: B036
                self.error = e
        return size

    def flush(self):
        pass

    def undo(self):
        """Restore the file as the session found it."""
        for off, old in reversed(self.saved):
            _pwrite_all(self.fd, old, off)
        os.ftruncate(self.fd, self.size0)

    def release(self):
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
        self.close()
