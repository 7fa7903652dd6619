"""The files of a run folder: ``run.json``, ``timeseries.csv``, ``solution.xdmf``, ``state.h5``,
``obstacles.xdmf`` (a problem with ``obstacles``; :mod:`.obstacle_xdmf`) (and ``checkpoint.npz``, see
:mod:`.restart`). docs/outputs.md describes them.

What a fault leaves (docs/outputs.md, "What survives which fault"): every file is complete up
to the last checkpoint whatever the moment a run is killed, and up to the last good step
when a write fails (no space left, a file deleted or replaced by someone else): the run then
stops with :class:`RunFileError`, one line, ``run.json`` saying ``"failed"``.
"""
import errno
import os
import sys
from pathlib import Path

from sdm_dolfinx.errors import StepError
from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.io import checkpoint
from sdm_dolfinx.io import journal
from sdm_dolfinx.io.journal import FileVanished, JournaledFile
from sdm_dolfinx.io.obstacle_xdmf import BOX_FACTOR, NAME as OBSTACLES_XDMF, ObstacleWriter
from sdm_dolfinx.io.series_files import CSVWriter, StateWriter
from sdm_dolfinx.io.xdmf_writer import XDMFWriter

#: the HDF5 files of a run, written through their undo logs (:mod:`.journal`)
H5_FILES = ("solution.h5", "state.h5")


class RunFileError(StepError):
    """A file of the run folder could not be written: no space left, a file deleted or
    replaced during the run, an I/O error. The run stops as failed (a StepError: the command
    line reports it in one line, exit status 1); ``no_space`` tells a full disc."""

    def __init__(self, message, no_space=False):
        super().__init__(message)
        self.no_space = no_space


def file_error(e, path=None):
    """The one-line :class:`RunFileError` of an OSError met while writing ``path``."""
    path = getattr(e, "filename", None) or path
    if isinstance(e, FileVanished):
        return RunFileError(f"{path} was deleted or replaced during the run")
    if getattr(e, "errno", None) in (errno.ENOSPC, errno.EDQUOT):
        return RunFileError(f"no space left on device while writing {path}", no_space=True)
    return RunFileError(f"cannot write {path}: {getattr(e, 'strerror', None) or e}")


def agree(comm, func, *args, path=None):
    """``func(*args)`` on every rank; an OSError (on any rank) is raised on every rank as the
    same :class:`RunFileError`, a ValueError (a kept file that is not this run's) as the same
    CheckpointError: no rank is left waiting in the next collective call."""
    err, out = None, None
    try:
        out = func(*args)
    except OSError as e:
        err = ("file", str(file_error(e, path)), file_error(e, path).no_space)
    except ValueError as e:
        err = ("match", str(e), False)
    errs = comm.allgather(err)
    first = next((e for e in errs if e is not None), None)
    if first is not None:
        if first[0] == "match":
            raise checkpoint.CheckpointError(first[1])
        raise RunFileError(first[1], no_space=first[2])
    return out


class RunFiles:
    """Open (or, on restart, continue) the files of ``out`` for one run (collective).

    Args:
        out: the folder (created if missing).
        discretisation: the run's Discretisation.
        series: its time series (``columns``, ``load_rows``: :class:`sdm_dolfinx.run.result.TimeSeries`;
            filled with the kept rows on restart).
        info: the ``run.json`` dict (written now and by :meth:`update`).
        restart: ``None`` for a new run, else ``(first step, files)`` with ``files`` the
            checkpoint's record of them (:meth:`record`; None for a checkpoint of an older
            version).
        write_every: the fields are written every K steps.
        block: V is the (U, V) block system's velocity in H^h (mass ``"consistent"``), else Vbar in W^h.
        friction: the run has friction: :meth:`fields` takes the step's tangential multipliers and
            slip set, written as the XDMF's friction fields.

    Raises:
        RunFileError: a file could not be written (nothing of the previous run is lost).
        checkpoint.CheckpointError: (restart) the kept files do not match the run.
    """

    def __init__(self, out, discretisation, series, info, fingerprint, restart, write_every, dt, block=False,
                 friction=False):
        self.comm, self.out, self.info, self.dt = discretisation.comm, Path(out), info, dt
        self.write_every = write_every or 10
        self.last_row = -1
        comm, out = self.comm, self.out
        self.csv = self.xdmf = self.state = self.obstacles = None
        self.has_obstacles = False
        self.journals = {name: None for name in H5_FILES}
        first = restart[0] if restart is not None else 0
        if restart is None:
            agree(comm, self._clear, path=out)
        else:
            restart = self._restore(first, restart[1])
        self._write_info()
        csv = out / "timeseries.csv"
        if restart is not None:
            rows = agree(comm, lambda: checkpoint.truncate_csv(csv, first) if comm.rank == 0 else None, path=csv)
            rows = comm.bcast(rows, root=0)
            series.load_rows(rows[1:])
            self.last_row = first
        append = restart is not None
        self.csv = agree(comm, CSVWriter, csv, series.columns, comm, append, path=csv)
        xsteps = restart["solution"] if append else None
        self.xdmf = agree(comm, XDMFWriter, out / "solution.xdmf", discretisation, dt, block, friction,
                          self.journals["solution.h5"], xsteps, path=out / "solution.h5")
        self.state = agree(comm, StateWriter, out / "state.h5", discretisation, block, fingerprint,
                           self.journals["state.h5"], not (append and restart["state"]), path=out / "state.h5")
        self.state_missing = append and not restart["state"]
        self.obstacles = self._obstacle_writer(discretisation, xsteps or [])

    def _obstacle_writer(self, discretisation, kept):
        """The writer of ``obstacles.xdmf`` on rank 0 (None elsewhere, and without obstacles): their
        surfaces clipped to the body's reference bounding box grown by BOX_FACTOR (collective)."""
        import numpy as np
        from mpi4py import MPI
        from sdm_dolfinx.obstacles.surface import enlarged_box
        problem = discretisation.problem
        obstacles = list(getattr(problem, "obstacles", None) or [])
        self.has_obstacles = bool(obstacles)          # the same on every rank
        if not obstacles:
            return None
        x = problem.mesh.geometry.x
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        self.comm.Allreduce(x.min(axis=0) if len(x) else lo.copy(), lo, op=MPI.MIN)
        self.comm.Allreduce(x.max(axis=0) if len(x) else hi.copy(), hi, op=MPI.MAX)
        box = enlarged_box(lo, hi, BOX_FACTOR)
        path = self.out / OBSTACLES_XDMF
        kept = [(int(n), int(n) * self.dt) for n in kept]
        return agree(self.comm, lambda: ObstacleWriter(path, obstacles, box, kept) if self.comm.rank == 0 else None,
                     path=path)

    # ------------------------------------------------------------------ new run / restart
    def _clear(self):
        """A new run: what a previous run left here must not be resumed or restored (rank 0)."""
        if self.comm.rank == 0:
            self.out.mkdir(parents=True, exist_ok=True)
            (self.out / checkpoint.CHECKPOINT).unlink(missing_ok=True)
            (self.out / OBSTACLES_XDMF).unlink(missing_ok=True)           # a previous run's obstacles
            for name in H5_FILES:
                journal.undo_path(self.out / name).unlink(missing_ok=True)
                self.journals[name] = JournaledFile(self.out / name)

    def _restore(self, first, files):
        """Bring the HDF5 files back to the checkpoint (rank 0, then agreed): ``{"solution":
        steps in solution.h5 or None, "state": kept?}``. A file that is missing or cannot be
        restored is moved aside (``NAME.damaged.h5``) and started again from step ``first``,
        with one warning line."""
        def restore():
            if self.comm.rank != 0:
                return None
            out, res, notes = self.out, {}, []
            for name in H5_FILES:
                stem = name[:-3]
                path = out / name
                status = "old" if files is None else journal.rollback(path, files["token"], files[name]["size"])
                ok = status == "ok" and checkpoint.readable_h5(path)
                if ok:
                    jf = JournaledFile(path, files[name]["size"], files["token"])
                    jf.reset_log(files["token"], files[name]["size"])     # what it held is applied
                    self.journals[name] = jf
                else:
                    moved, tag = [], "old" if status == "old" else "damaged"
                    for src in (path, out / f"{stem}.xdmf"):
                        if src.exists():
                            dst = src.with_name(f"{stem}.{tag}{src.suffix}")
                            os.replace(src, dst)
                            moved.append(dst.name)
                    journal.undo_path(path).unlink(missing_ok=True)
                    self.journals[name] = JournaledFile(path)
                    why = {"missing": "is missing", "short": "was cut short",
                           "old": "was written by an older version"}.get(status, "could not be read")
                    notes.append(f"{name} {why}" + (f" (moved to {', '.join(moved)})" if moved else ""))
                res[stem] = (files["solution.h5"]["steps"] if stem == "solution" else True) if ok else None
            if notes:
                print(f"warning: {'; '.join(notes)}: the fields continue in a new file from step {first}",
                      file=sys.stderr, flush=True)
            return res
        res = agree(self.comm, restore, path=self.out)
        return self.comm.bcast(res, root=0)

    # ----------------------------------------------------------------------------- writing
    def row(self, row):
        """Append a time-series row to ``timeseries.csv``."""
        agree(self.comm, self.csv.write, row, path=self.out / "timeseries.csv")
        self.last_row = int(row["step"])

    def fields(self, n, U, V, lam, lam_t=None, slipping=None):
        """Write the fields of step ``n`` to ``state.h5`` and ``solution.xdmf`` (with friction, the
        step's ``lam_t`` and ``slipping`` too: :meth:`XDMFWriter.write`): all or nothing. When one
        write fails (a full disc), what the others wrote of step ``n`` is taken back out, and so is
        its time-series row, so that every file ends at the last good step (the time series held a
        step that state.h5 did not)."""
        if self.has_obstacles:
            try:
                agree(self.comm, lambda: self.obstacles.write(n, n * self.dt) if self.comm.rank == 0 else None,
                      path=self.out / OBSTACLES_XDMF)
            except RunFileError:
                self._take_back(n)
                raise
        try:
            agree(self.comm, self.state.write, U, V, n, n * self.dt, path=self.out / "state.h5")
        except RunFileError:
            self._take_back(n)
            raise
        try:
            agree(self.comm, self.xdmf.write, U, V, lam, lam > 0, n, lam_t, slipping, path=self.out / "solution.h5")
        except RunFileError:
            self._take_back(n, "state.h5")
            raise

    def _take_back(self, n, *written):
        """Undo step ``n``'s writes of the HDF5 files ``written`` and its row of timeseries.csv (best
        effort: none of it needs space; the step's error is the one reported)."""
        def undo():
            if self.comm.rank == 0:
                if self.obstacles is not None:
                    self.obstacles.drop(n)
                for name in written:
                    self.journals[name].undo_last()
                if self.last_row == n:
                    self.csv.drop_last()
        try:
            agree(self.comm, undo, path=self.out)
        except RunFileError:
            return
        if self.last_row == n:
            self.last_row = n - 1

    def state_write(self, U, V, n):
        """Write step ``n`` to ``state.h5`` only (a restart that starts a new state.h5)."""
        agree(self.comm, self.state.write, U, V, n, n * self.dt, path=self.out / "state.h5")

    def due(self, n, nsteps):
        """Whether step ``n``'s fields are written (every ``write_every`` steps, and the last)."""
        return n % self.write_every == 0 or n == nsteps

    def update(self, **entries):
        """Update ``run.json`` with ``entries``."""
        self.info.update(entries)
        self._write_info()

    def _write_info(self):
        path = self.out / "run.json"
        agree(self.comm, lambda: atomic_write_text(path, json_text(self.info)) if self.comm.rank == 0 else None,
              path=path)

    # ------------------------------------------------------------------------ checkpoints
    def record(self, token):
        """What a checkpoint stores of the files (on every rank): the token of this commit,
        each HDF5 file's size, the steps in solution.h5."""
        def sizes():
            if self.comm.rank != 0:
                return None
            return {name: {"size": self.journals[name].size()} for name in H5_FILES}
        rec = self.comm.bcast(agree(self.comm, sizes, path=self.out), root=0)
        rec["token"] = token
        rec["solution.h5"]["steps"] = sorted(self.comm.bcast(self.xdmf.steps if self.comm.rank == 0 else None,
                                                             root=0))
        return rec

    def commit(self, token):
        """The checkpoint ``token`` is written: the files as they are now are its state."""
        def commit():
            if self.comm.rank == 0:
                for name in H5_FILES:
                    self.journals[name].commit(token)
        agree(self.comm, commit, path=self.out)

    def tidy(self):
        """A finished run: its undo logs are of no more use (rank 0)."""
        if self.comm.rank == 0:
            for name in H5_FILES:
                if self.journals[name] is not None:
                    self.journals[name].close()
                journal.undo_path(self.out / name).unlink(missing_ok=True)

    def close(self):
        if self.csv is not None:
            self.csv.close()
        for jf in self.journals.values():
            if jf is not None:
                jf.close()
