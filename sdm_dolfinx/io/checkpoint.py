"""Checkpoints: the full state of a run (U, V, active set, the step solver's history, step,
time, parameters, mesh identity, and the state of the run's files) in one
``checkpoint.npz``, written atomically (temporary file, then rename).

Values are stored with the coordinates of their dofs (and the active constraints by their
vertex coordinates), not in the global numbering: that numbering depends on the mesh
partition, which a partitioner need not reproduce from one process to the next (it does
not for the gmsh disc on dolfinx 0.9). On restart each rank finds its dofs by coordinates,
so any partition (and any number of ranks) reads the same state; the mesh fingerprint and
the parameters are checked as well.
"""
import json
import zipfile
import zlib
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.mpiutil import atomic_write, atomic_write_text, gather_rows

CHECKPOINT = "checkpoint.npz"


class CheckpointError(SdmError, RuntimeError):
    """A checkpoint is missing, unreadable or does not match the run."""


def mesh_fingerprint(msh):
    """Global vertex and cell counts and coordinate moments: equal meshes, equal prints."""
    comm = msh.comm
    tdim = msh.topology.dim
    nv = msh.topology.index_map(0).size_global
    nc = msh.topology.index_map(tdim).size_global
    nx = msh.geometry.index_map().size_local
    x = msh.geometry.x[:nx]
    moments = comm.allreduce(np.array([x.sum(), (x ** 2).sum()]), op=MPI.SUM)
    return {"vertices": int(nv), "cells": int(nc), "x_sum": float(moments[0]), "x2_sum": float(moments[1])}


def same_fingerprint(a, b, rtol=1e-12):
    """True when two mesh fingerprints (vertex and cell counts, coordinate sums) agree to ``rtol``."""
    return (a["vertices"] == b["vertices"] and a["cells"] == b["cells"]
            and all(abs(a[k] - b[k]) <= rtol * max(1.0, abs(b[k])) for k in ("x_sum", "x2_sum")))


def _owned(space, vec):
    """(coordinates, values) of the owned dof blocks of a vector of ``space``."""
    n = space.dofmap.index_map.size_local
    bs = space.dofmap.index_map_bs
    return space.tabulate_dof_coordinates()[:n], np.array(vec.array).reshape(n, bs)


def save(folder, comm, fields, active_x, meta, extra=None):
    """Write ``folder/checkpoint.npz`` atomically (collective gathers, then rank 0 writes; no
    barrier after it: an OSError on rank 0, a full disc, leaves the old checkpoint and is
    for the caller to share, see :func:`sdm_dolfinx.io.run_files.agree`).

    Args:
        fields: ``{"U": (space, vec), "V": (space, vec)}``.
        active_x: (n, 3) coordinates of this rank's active constrained vertices.
        extra: arrays stored as they are (rank 0's).
    """
    data = dict(extra or {})
    for name, (space, vec) in fields.items():
        x, v = _owned(space, vec)
        data[name + "_x"], data[name] = gather_rows(x, comm), gather_rows(v, comm)
    data["active_x"] = gather_rows(np.asarray(active_x, dtype=float).reshape(-1, 3), comm)
    if comm.rank == 0:
        def write(tmp):
            with open(tmp, "wb") as fh:         # a file object: savez would append .npz to a name
                np.savez(fh, meta=json.dumps(meta), **data)
        atomic_write(Path(folder) / CHECKPOINT, write)


def _match(saved_x, x, scale):
    """Index into saved_x of each point of x (exact match up to round-off), None (no match) or "shared"
    (two saved points at one point of x: two bodies touching in the reference mesh)."""
    from scipy.spatial import cKDTree
    if len(x) == 0:
        return np.zeros(0, dtype=np.int64)
    k = 2 if len(saved_x) > 1 else 1
    d, idx = cKDTree(saved_x).query(x, k=k)
    if k == 2:
        if np.any(d[:, 1] <= 1e-9 * scale):
            return "shared"
        d, idx = d[:, 0], idx[:, 0]
    return idx if np.all(d <= 1e-9 * scale) else None


def restore(data, fields, comm):
    """Set the owned entries of each field's vector from ``data`` (of :func:`load`)."""
    for name, (space, vec) in fields.items():
        x, _ = _owned(space, vec)
        scale = max(float(np.abs(data[name + "_x"]).max(initial=0.0)), 1.0)
        idx = _match(data[name + "_x"], x, scale)
        if comm.allreduce(isinstance(idx, str), op=MPI.LOR):
            raise CheckpointError(f"the checkpoint names the {name} dofs by their positions, and two of them share "
                                  f"one (bodies touching in the reference mesh): this run cannot be restarted; "
                                  f"start the bodies apart")
        if comm.allreduce(idx is None, op=MPI.LOR):
            raise CheckpointError(f"the checkpoint's {name} dofs do not match this mesh")
        vec.array[:] = data[name][idx].reshape(-1)


def active_mask(data, cx):
    """Which of this rank's constrained vertices (coordinates (3, n)) were active."""
    saved = data["active_x"]
    if len(saved) == 0 or cx.shape[1] == 0:
        return np.zeros(cx.shape[1], dtype=bool)
    from scipy.spatial import cKDTree
    scale = max(float(np.abs(saved).max()), 1.0)
    d, _ = cKDTree(saved).query(cx.T)
    return d <= 1e-9 * scale


def load(folder, comm):
    """(arrays, meta) of ``folder/checkpoint.npz``, on every rank.

    Raises:
        CheckpointError: missing, or damaged (truncated, bad CRC, not an .npz, no meta), in
            one line; nothing is changed.
    """
    path = Path(folder) / CHECKPOINT
    data, err = None, None
    if comm.rank == 0:
        try:
            with np.load(path, allow_pickle=False) as f:
                data = ({k: f[k] for k in f.files if k != "meta"}, json.loads(str(f["meta"])))
        except FileNotFoundError:
            err = f"no checkpoint in {folder} (run with --checkpoint-every K, or interrupt with SIGINT/SIGTERM)"
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as e:
            why = " ".join(f"{type(e).__name__}: {e}".split())
            err = f"cannot read {path}: it is damaged or not a checkpoint ({why})"
    err = comm.bcast(err, root=0)
    if err:
        raise CheckpointError(err)
    return comm.bcast(data, root=0)


def previous_run_id(folder, comm):
    """The ``run_id`` of ``folder/run.json`` (None without one), on every rank."""
    rid = None
    if comm.rank == 0:
        try:
            rid = json.loads((Path(folder) / "run.json").read_text()).get("run_id")
        except (OSError, ValueError, AttributeError):
            rid = None
    return comm.bcast(rid, root=0)


def readable_h5(path):
    """True when every object of the HDF5 file ``path`` can be opened (a damaged header or
    object raises)."""
    import h5py
    try:
        with h5py.File(path, "r") as h5:
            h5.visititems(lambda name, obj: None)
        return True
    except Exception:               # noqa: BLE001  (h5py raises OSError, KeyError, RuntimeError, ...)
        return False


def check_series(folder, step, comm):
    """Before a restart touches anything: the time series must reach the checkpoint's step
    (else the checkpoint is not this folder's run). Raises CheckpointError (nothing changed)."""
    err = None
    if comm.rank == 0:
        folder = Path(folder)
        csv = folder / "timeseries.csv"
        try:
            rows = _whole_rows(csv.read_text()) if csv.exists() else []
            last = max((int(ln.split(",", 1)[0]) for ln in rows[1:]), default=-1)
        except (OSError, ValueError, UnicodeDecodeError) as e:
            rows, last = [], -1
            err = f"{csv} cannot be read ({e}): the run cannot continue"
        if err is None and not csv.exists():
            err = f"{csv} is missing: the run cannot continue without its time series"
        elif err is None and last < step:
            err = (f"{csv} ends at step {last}, before the checkpoint's step {step}: the checkpoint is "
                   f"not from the run in {folder}")
    err = comm.bcast(err, root=0)
    if err:
        raise CheckpointError(err)


def _whole_rows(text):
    """The header and the complete rows of a CSV's text. A run killed while writing may leave
    a partial last line: every row is written with its newline in one call, so a last line
    without one is torn (whatever its commas say), and a row must have every column."""
    lines = text.splitlines()
    if not lines:
        return []
    if not text.endswith("\n"):
        lines = lines[:-1]
    width = len(lines[0].split(",")) if lines else 0
    return lines[:1] + [ln for ln in lines[1:] if ln and len(ln.split(",")) == width
                        and all(field.strip() for field in ln.split(","))]


def truncate_csv(path, last_step, comm=None):
    """Keep the header and the rows of steps <= last_step, atomically; returns those lines.
    With ``comm``: rank 0 does it and every rank gets the lines; without: the calling
    process does it (an OSError, a full disc, is then the caller's to share)."""
    if comm is None:
        lines = _whole_rows(Path(path).read_text())
        keep = lines[:1] + [ln for ln in lines[1:] if int(ln.split(",", 1)[0]) <= last_step]
        atomic_write_text(path, "\n".join(keep) + "\n")
        return keep
    return comm.bcast(truncate_csv(path, last_step) if comm.rank == 0 else None, root=0)
