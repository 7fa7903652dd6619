"""The time series' files: ``timeseries.csv`` (a row per step) and ``state.h5`` (the native dof
vectors of U and V every K steps); the XDMF fields are :mod:`.xdmf_writer`'s.

Only rank 0 writes, after a gather: CSV rows with one system call each, and the HDF5 file through
:class:`~sdm_dolfinx.io.journal.JournaledFile` (crash-safe: a kill or a full disc never damages
what an earlier step or checkpoint wrote). The writers raise OSError
(:class:`~sdm_dolfinx.io.journal.FileVanished` for a file deleted or replaced during the run) on
rank 0 only; :class:`~sdm_dolfinx.io.run_files.RunFiles` makes every rank agree.

Every file is independent of the partition of the process that wrote it: the rows of state.h5
are in the order of the dof coordinates stored in it (a continuing process maps its own order
onto them), the XDMF mesh and fields in the mesh's input node order.
"""
import errno
import os
from pathlib import Path

import numpy as np

from sdm_dolfinx.mpiutil import gather_blocks, gather_vec
from sdm_dolfinx.io.journal import FileVanished
from sdm_dolfinx.io.xdmf_writer import match_rows


class CSVWriter:
    """timeseries.csv, one whole line per step written with one system call (rank 0).

    A line that cannot be written whole (no space left) is cut off again, so the file never
    ends with a partial row; a file deleted or replaced during the run is noticed at the next
    row (:class:`FileVanished`)."""

    def __init__(self, path, columns, comm, append=False):
        self.comm, self.columns, self.path = comm, tuple(columns), Path(path)
        self.fd = None
        if comm.rank == 0:
            flags = os.O_WRONLY | os.O_CREAT | (os.O_APPEND if append else os.O_TRUNC)
            self.fd = os.open(self.path, flags, 0o644)
            self.inode, self.size = os.fstat(self.fd).st_ino, os.fstat(self.fd).st_size
            self.before_last = None         # the size before the last row (drop_last)
            if not append:
                self._append(",".join(self.columns) + "\n")

    def _append(self, line):
        data = line.encode()
        try:
            st = os.stat(self.path)
        except FileNotFoundError:
            raise FileVanished(self.path) from None
        if st.st_ino != self.inode:
            raise FileVanished(self.path)
        try:
            n = os.pwrite(self.fd, data, self.size)
            if n != len(data):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path))
        except OSError:
            os.ftruncate(self.fd, self.size)        # no partial row
            raise
        self.before_last = self.size
        self.size += n

    def drop_last(self):
        """Cut the last row off again (rank 0 only; needs no space): its step's other files could
        not be written."""
        if self.fd is not None and self.before_last is not None:
            os.ftruncate(self.fd, self.before_last)
            self.size, self.before_last = self.before_last, None

    def write(self, row):
        """Append one row (a dict column -> value) (rank 0 only)."""
        if self.fd is not None:
            self._append(",".join(_fmt(row[c]) for c in self.columns) + "\n")

    def close(self):
        """Close the file (rank 0 only)."""
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


def _fmt(v):
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return repr(float(v))


class StateWriter:
    """state.h5: the native dof vectors of U and V every K steps, for post-processing.

    XDMF shows ParaView vertex interpolants; this file keeps the exact coefficients together
    with each dof block's coordinates (so that a reader on any number of ranks can match
    them) and the mesh fingerprint. Rows are in the dof order of the process that created the
    file (as its ``dof_coordinates`` say); a process continuing the file (a restart, whose
    partition may differ) maps its own order onto it by the coordinates. Written by rank 0
    with (serial) h5py after a gather; datasets ``U``, ``V`` (one row per write), ``t``,
    ``step``; groups ``W`` and ``V_space`` hold ``dof_coordinates`` and ``block_size``.

    Args:
        block: V is the (U, V) block system's velocity in H^h (mass ``"consistent"``), else Vbar in W^h.
        journal: the file's :class:`JournaledFile` (rank 0; None elsewhere).
        new: create the file (else continue it: it holds the rows up to the restart).
    """

    def __init__(self, path, discretisation, block, fingerprint, journal=None, new=True):
        self.comm, self.path, self.journal = discretisation.comm, Path(path), journal
        vspace = discretisation.H if block else discretisation.W
        spaces = (("W", discretisation.W), ("V_space", vspace))
        coords = {name: gather_blocks(sp, sp.tabulate_dof_coordinates(), self.comm) for name, sp in spaces}
        bs = {name: sp.dofmap.index_map_bs for name, sp in spaces}
        self.bs = bs
        self.maps = {"W": None, "V_space": None}
        if self.comm.rank != 0:
            return
        if not new:
            with journal.h5("r") as h5:
                for name in ("W", "V_space"):
                    if int(h5[name].attrs["block_size"]) != bs[name]:
                        raise ValueError(f"{self.path}: block size {int(h5[name].attrs['block_size'])} of "
                                         f"{name}, this run has {bs[name]}")
                    self.maps[name] = match_rows(h5[name]["dof_coordinates"][:], coords[name],
                                                  f"{self.path} ({name})")
            return
        with journal.h5("w") as h5:
            for name in ("W", "V_space"):
                g = h5.create_group(name)
                g.create_dataset("dof_coordinates", data=coords[name])
                g.attrs["block_size"] = bs[name]
            nu = coords["W"].shape[0] * bs["W"]
            nv = coords["V_space"].shape[0] * bs["V_space"]
            # float64: h5py's default float32 would lose half the digits
            h5.create_dataset("U", shape=(0, nu), maxshape=(None, nu), chunks=(1, max(nu, 1)), dtype="f8")
            h5.create_dataset("V", shape=(0, nv), maxshape=(None, nv), chunks=(1, max(nv, 1)), dtype="f8")
            h5.create_dataset("t", shape=(0,), maxshape=(None,), dtype="f8")
            h5.create_dataset("step", shape=(0,), maxshape=(None,), dtype="i8")
            h5.attrs["V_is"] = "V in H^h (block system)" if block else "Vbar in W^h"
            for k, v in fingerprint.items():
                h5.attrs["mesh_" + k] = v

    def _in_file_order(self, a, name):
        idx = self.maps[name]
        if idx is None:
            return a
        bs = self.bs[name]
        return a.reshape(-1, bs)[idx].reshape(-1)

    def write(self, U, V, step, t):
        """Gather U and V to rank 0 and append them, with the step and time, to state.h5."""
        u, v = gather_vec(U, self.comm), gather_vec(V, self.comm)
        if self.comm.rank == 0:
            u, v = self._in_file_order(u, "W"), self._in_file_order(v, "V_space")
            with self.journal.h5() as h5:
                n = h5["t"].shape[0]
                for name, val in (("U", u), ("V", v), ("t", t), ("step", step)):
                    h5[name].resize(n + 1, axis=0)
                    h5[name][n] = val
