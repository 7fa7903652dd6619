"""Checkpoints: the full state of a run (U, V, active set, step, time, parameters, mesh
identity) in one ``checkpoint.npz``, written atomically (temporary file, then rename).

Values are stored with the coordinates of their dofs (and the active constraints by their
vertex coordinates), not in the global numbering: that numbering depends on the mesh
partition, which a partitioner need not reproduce from one process to the next (it does
not for the gmsh disc on dolfinx 0.9). On restart each rank finds its dofs by coordinates,
so any partition (and any number of ranks) reads the same state; the mesh fingerprint and
the parameters are checked as well.
"""
import json
import os
import re
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.mpiutil import atomic_write, atomic_write_text, gather_rows

CHECKPOINT = "checkpoint.npz"


class CheckpointError(RuntimeError):
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


def save(folder, comm, fields, active_x, meta):
    """Write ``folder/checkpoint.npz`` atomically (collective).

    Args:
        fields: ``{"U": (space, vec), "V": (space, vec)}``.
        active_x: (n, 3) coordinates of this rank's active constrained vertices.
    """
    data = {}
    for name, (space, vec) in fields.items():
        x, v = _owned(space, vec)
        data[name + "_x"], data[name] = gather_rows(x, comm), gather_rows(v, comm)
    data["active_x"] = gather_rows(np.asarray(active_x, dtype=float).reshape(-1, 3), comm)
    if comm.rank == 0:
        def write(tmp):
            with open(tmp, "wb") as fh:         # a file object: savez would append .npz to a name
                np.savez(fh, meta=json.dumps(meta), **data)
        atomic_write(Path(folder) / CHECKPOINT, write)
    comm.Barrier()


def _match(saved_x, x, scale):
    """Index into saved_x of each point of x (exact match up to round-off), or None."""
    from scipy.spatial import cKDTree
    if len(x) == 0:
        return np.zeros(0, dtype=np.int64)
    d, idx = cKDTree(saved_x).query(x)
    return idx if np.all(d <= 1e-9 * scale) else None


def restore(data, fields, comm):
    """Set the owned entries of each field's vector from ``data`` (of :func:`load`)."""
    for name, (space, vec) in fields.items():
        x, _ = _owned(space, vec)
        scale = max(float(np.abs(data[name + "_x"]).max(initial=0.0)), 1.0)
        idx = _match(data[name + "_x"], x, scale)
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
    """(arrays, meta) of ``folder/checkpoint.npz``, on every rank."""
    path = Path(folder) / CHECKPOINT
    data, err = None, None
    if comm.rank == 0:
        try:
            with np.load(path) as f:
                data = ({k: f[k] for k in f.files if k != "meta"}, json.loads(str(f["meta"])))
        except FileNotFoundError:
            err = f"no checkpoint in {folder} (run with --checkpoint-every K, or interrupt with SIGINT/SIGTERM)"
        except (OSError, ValueError, KeyError) as e:
            err = f"cannot read {path}: {e}"
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


def _readable_h5(path):
    import h5py
    try:
        with h5py.File(path, "r") as h5:
            h5.visit(lambda name: None)         # walks every object: a damaged header raises
        return True
    except (OSError, RuntimeError, KeyError, ValueError):
        return False


def check_outputs(folder, step, comm):
    """Before a restart touches anything: the time series must reach the checkpoint's step
    (else the checkpoint is not this folder's run), and HDF5 files that a kill during a
    write left unreadable are moved aside (``solution.damaged.h5`` ...) so that the run
    continues them in new files. Returns ``{"solution": ok, "state": ok, "moved": [names]}``
    on every rank; raises CheckpointError (nothing changed) when the series is too short."""
    res, err = None, None
    if comm.rank == 0:
        folder = Path(folder)
        csv = folder / "timeseries.csv"
        rows = _whole_rows(csv.read_text().splitlines()) if csv.exists() else []
        last = max((int(ln.split(",", 1)[0]) for ln in rows[1:]), default=-1)
        if last < step:
            err = (f"{csv} ends at step {last}, before the checkpoint's step {step}: the checkpoint is "
                   f"not from the run in {folder}")
        else:
            res = {"moved": []}
            for stem in ("solution", "state"):
                h5 = folder / f"{stem}.h5"
                res[stem] = h5.exists() and _readable_h5(h5)
                if not res[stem]:               # its files (if any) go aside; new ones are started
                    for src in (h5, folder / f"{stem}.xdmf"):
                        if src.exists():
                            dst = src.with_name(f"{stem}.damaged{src.suffix}")
                            os.replace(src, dst)
                            res["moved"].append(dst.name)
    err = comm.bcast(err, root=0)
    if err:
        raise CheckpointError(err)
    return comm.bcast(res, root=0)


def _whole_rows(lines):
    """The header and the rows with all its columns (a run killed while writing may leave a
    partial last line)."""
    if not lines:
        return []
    width = len(lines[0].split(","))
    return lines[:1] + [ln for ln in lines[1:] if ln and len(ln.split(",")) == width]


def truncate_csv(path, last_step, comm):
    """Keep the header and the rows of steps <= last_step (rank 0); returns those rows."""
    rows = None
    if comm.rank == 0:
        lines = _whole_rows(Path(path).read_text().splitlines())
        keep = lines[:1] + [ln for ln in lines[1:] if int(ln.split(",", 1)[0]) <= last_step]
        atomic_write_text(path, "\n".join(keep) + "\n")
        rows = keep
    return comm.bcast(rows, root=0)


_GRID = re.compile(r'\n\s*<Grid Name="[^"]*" GridType="Uniform">\s*<xi:include[^>]*/>\s*'
                   r'<Time Value="([^"]+)" />.*?</Grid>', re.S)
_ITEM = re.compile(r'Format="HDF">[^:<]+:([^<]+)</DataItem>')


def truncate_xdmf(xdmf, t_last, comm):
    """Drop the time steps after t_last from an XDMF file and its HDF5 datasets (rank 0),
    so that appending continues it without duplicates."""
    if comm.rank == 0 and Path(xdmf).exists():
        text = Path(xdmf).read_text()
        drop = []

        def keep(m):
            if float(m.group(1)) > t_last * (1 + 1e-12) + 1e-300:
                drop.extend(_ITEM.findall(m.group(0)))
                return ""
            return m.group(0)
        text = _GRID.sub(keep, text)
        if drop:
            import h5py
            with h5py.File(Path(xdmf).with_suffix(".h5"), "a") as h5:
                for name in drop:
                    if name in h5:
                        del h5[name]
        atomic_write_text(xdmf, text)
    comm.Barrier()
