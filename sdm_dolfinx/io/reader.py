"""Reading a finished run back: ``run.json``, ``timeseries.csv`` and the fields of ``state.h5``.

A run folder holds ``run.json`` (what was run), ``timeseries.csv`` (one row per step) and
``state.h5`` (the native dof vectors of U and V every ``write_every`` steps, with the dof
coordinates). Files are read on rank 0 (Debian's h5py is serial) and broadcast or scattered;
:class:`StateReader` matches the stored dofs to the rebuilt spaces by their coordinates, so a
run written on k ranks is read on any number of ranks.
"""
import csv
from pathlib import Path

from mpi4py import MPI

import numpy as np
from dolfinx import fem

from sdm_dolfinx.mpiutil import on_rank0
from sdm_dolfinx.io.checkpoint import mesh_fingerprint, same_fingerprint
from sdm_dolfinx.io.folder import RunFolderError


class PostprocessError(RunFolderError):
    """A run folder cannot be post-processed (missing or inconsistent files)."""


def read_timeseries(folder, comm=MPI.COMM_WORLD, name="timeseries.csv"):
    """``folder/timeseries.csv`` as {column: array}, on every rank (rows cut short are skipped)."""
    path = Path(folder) / name

    def read():
        if not path.exists():
            raise PostprocessError(f"{folder}: no {name}")
        with open(path) as fh:
            rows = [r for r in csv.reader(fh) if r]
        if not rows:
            raise PostprocessError(f"{path}: empty (no header)")
        header, rows = rows[0], rows[1:]
        rows = [r for r in rows if len(r) == len(header)]
        return {c: np.array([float(r[i]) for r in rows]) for i, c in enumerate(header)}
    return on_rank0(comm, read, wrap=PostprocessError)


def _owned_block_coordinates(V):
    n = V.dofmap.index_map.size_local
    return V.tabulate_dof_coordinates()[:n]


class StateReader:
    """Reads ``state.h5`` into Functions of the rebuilt spaces, on any number of ranks.

    The file stores vectors in the writing run's global numbering together with each dof's
    coordinates; here every owned dof block of the rebuilt space is matched to the stored
    block at the same point (k-d tree), which also checks that the meshes agree.

    Args:
        folder: the run folder.
        W, Vs: the rebuilt displacement and velocity spaces (:func:`~sdm_dolfinx.post.rebuild_spaces`).
        comm: the spaces' communicator.
    """

    def __init__(self, folder, W, Vs, comm=MPI.COMM_WORLD):
        self.comm, self.path = comm, Path(folder) / "state.h5"
        head = on_rank0(comm, self._header, folder, wrap=PostprocessError)
        self.steps, self.t, self.dtype = head["steps"], head["t"], np.dtype(head["dtype"])
        self.V_is = head["V_is"]
        if head["mesh"] and not same_fingerprint(head["mesh"], mesh_fingerprint(W.mesh), rtol=1e-10):
            raise PostprocessError(f"{folder}: the rebuilt mesh differs from the run's mesh "
                                   f"(state.h5 {head['mesh']}, rebuilt {mesh_fingerprint(W.mesh)})")
        self.W, self.Vs = W, Vs
        self._maps = {}
        for key, sp, coords, bs in (("U", W, head["W"], head["bs_W"]), ("V", Vs, head["V"], head["bs_V"])):
            if bs != sp.dofmap.index_map_bs:
                raise PostprocessError(f"{folder}: block size {bs} in state.h5, {sp.dofmap.index_map_bs} rebuilt")
            self._maps[key] = self._match(sp, coords, bs)

    def _header(self, folder):
        """Steps, times, dof coordinates and mesh fingerprint of state.h5 (rank 0)."""
        import h5py
        if not self.path.exists():
            raise PostprocessError(f"{folder}: no state.h5 (a run writes it when given an output folder)")
        with h5py.File(self.path, "r") as h5:
            return {"steps": h5["step"][:].astype(int), "t": h5["t"][:].astype(float),
                    "dtype": str(h5["U"].dtype),
                    "W": h5["W/dof_coordinates"][:], "bs_W": int(h5["W"].attrs["block_size"]),
                    "V": h5["V_space/dof_coordinates"][:], "bs_V": int(h5["V_space"].attrs["block_size"]),
                    "mesh": {k[5:]: v for k, v in h5.attrs.items() if k.startswith("mesh_")},
                    "V_is": str(h5.attrs.get("V_is", ""))}

    def _match(self, V, coords, bs):
        """Per rank, the stored entry of each owned entry of V (gathered on rank 0)."""
        from scipy.spatial import cKDTree
        mine = _owned_block_coordinates(V)
        scale = max(float(np.ptp(coords, axis=0).max()), 1.0) if len(coords) else 1.0
        tree = cKDTree(coords)
        k = 2 if len(coords) > 1 else 1
        dist, idx = tree.query(mine, k=k)
        if k == 2:
            shared = bool(len(mine)) and bool(dist[:, 1].min() <= 1e-9 * scale)
            if self.comm.allreduce(shared, op=MPI.LOR):         # every rank: a lone raise would hang the others
                raise PostprocessError("two stored dofs share one point (bodies touching in the reference mesh?): "
                                       "cannot match dofs by coordinates")
            dist, idx = dist[:, 0], idx[:, 0]
        bad = int(self.comm.allreduce(int(np.sum(dist > 1e-9 * scale)), op=MPI.SUM))
        if bad:
            raise PostprocessError(f"{bad} dofs of the rebuilt space have no stored dof at their point: "
                                   "the run's mesh or pair differs")
        entries = (idx[:, None] * bs + np.arange(bs)[None, :]).reshape(-1)
        n = self.comm.allreduce(len(entries), op=MPI.SUM)
        if n != len(coords) * bs:
            raise PostprocessError(f"the rebuilt space has {n} dofs, state.h5 {len(coords) * bs}")
        return self.comm.gather(entries, root=0)

    def __len__(self):
        return len(self.steps)

    def index_of_step(self, step):
        """Row of the stored step ``step`` (KeyError if that step was not written)."""
        hits = np.flatnonzero(self.steps == step)
        if not len(hits):
            raise KeyError(f"step {step} is not stored in {self.path}")
        return int(hits[-1])

    def _read_row(self, i):
        rows = None
        if self.comm.rank == 0:
            import h5py
            with h5py.File(self.path, "r") as h5:
                rows = (h5["U"][i].astype(float), h5["V"][i].astype(float))
        return rows

    def read(self, i, u=None, v=None):
        """Row ``i`` as Functions (u in W, v in the V space); pass Functions to fill them."""
        u = u if u is not None else fem.Function(self.W)
        v = v if v is not None else fem.Function(self.Vs)
        rows = self._read_row(i)
        for f, key, k in ((u, "U", 0), (v, "V", 1)):
            parts = [rows[k][m] for m in self._maps[key]] if self.comm.rank == 0 else None
            vals = self.comm.scatter(parts, root=0)
            f.x.array[:len(vals)] = vals
            f.x.scatter_forward()
        return u, v
