"""Checkpoints: the full state of a run (U, V, active set, step, time, parameters, mesh
identity) in one ``checkpoint.npz``, written atomically (temporary file, then rename).

Vectors are stored in the global (PETSc) numbering, so a restart needs the same number of
ranks as the run that wrote them (the mesh partition fixes that numbering); the mesh
fingerprint and the parameters are checked on restart.
"""
import json
import os
import re
from pathlib import Path

from mpi4py import MPI

import numpy as np

CHECKPOINT = "checkpoint.npz"


class CheckpointError(RuntimeError):
    """A checkpoint is missing, unreadable or does not match the run."""


def gather(vec, comm):
    """The global array of a PETSc vector, on rank 0 (None elsewhere)."""
    r0, _ = vec.getOwnershipRange()
    parts = comm.gather((r0, np.array(vec.array)), root=0)
    if comm.rank != 0:
        return None
    out = np.empty(vec.getSize())
    for start, a in parts:
        out[start:start + len(a)] = a
    return out


def scatter(arr, vec):
    """Set the owned entries of ``vec`` from the global array ``arr`` (present on every rank)."""
    r0, r1 = vec.getOwnershipRange()
    vec.array[:] = arr[r0:r1]


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
    return (a["vertices"] == b["vertices"] and a["cells"] == b["cells"]
            and all(abs(a[k] - b[k]) <= rtol * max(1.0, abs(b[k])) for k in ("x_sum", "x2_sum")))


def save(folder, comm, U, V, active_gidx, meta):
    """Write ``folder/checkpoint.npz`` atomically (collective)."""
    u, v = gather(U, comm), gather(V, comm)
    act = comm.gather(np.asarray(active_gidx, dtype=np.int64), root=0)
    if comm.rank == 0:
        path = Path(folder) / CHECKPOINT
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez(tmp, U=u, V=v, active=np.concatenate(act), meta=json.dumps(meta))
        os.replace(tmp, path)
    comm.Barrier()


def load(folder, comm):
    """(U, V, active global indices, meta) of ``folder/checkpoint.npz``, on every rank."""
    path = Path(folder) / CHECKPOINT
    data, err = None, None
    if comm.rank == 0:
        try:
            with np.load(path) as f:
                data = (f["U"], f["V"], f["active"], json.loads(str(f["meta"])))
        except FileNotFoundError:
            err = f"no checkpoint in {folder} (run with --checkpoint-every K, or interrupt with SIGINT/SIGTERM)"
        except (OSError, ValueError, KeyError) as e:
            err = f"cannot read {path}: {e}"
    err = comm.bcast(err, root=0)
    if err:
        raise CheckpointError(err)
    return comm.bcast(data, root=0)


def truncate_csv(path, last_step, comm):
    """Keep the header and the rows of steps <= last_step (rank 0); returns those rows."""
    rows = None
    if comm.rank == 0:
        lines = Path(path).read_text().splitlines()
        keep = [lines[0]] + [ln for ln in lines[1:] if ln and int(ln.split(",", 1)[0]) <= last_step
                             and len(ln.split(",")) == len(lines[0].split(","))]
        tmp = Path(str(path) + ".tmp")
        tmp.write_text("\n".join(keep) + "\n")
        os.replace(tmp, path)
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
        tmp = Path(str(xdmf) + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, xdmf)
    comm.Barrier()
