"""MPI and file helpers shared by every layer: gather to rank 0, run-on-rank-0-and-broadcast,
atomic writes and one JSON encoder. Imports nothing from the package (like :mod:`compat`).

Conventions (STYLE.md): only rank 0 writes CSV/JSON; every function taking ``comm`` is
collective unless it says otherwise.
"""
import json
import os
from pathlib import Path

import numpy as np


# ------------------------------------------------------------------------------ gathering
def gather_vec(vec, comm):
    """The global array of a PETSc vector on rank 0 (None elsewhere)."""
    r0, _ = vec.getOwnershipRange()
    return gather_ranges(r0, np.array(vec.array), vec.getSize(), comm)


def gather_ranges(start, values, size, comm):
    """Rows ``values`` that this rank owns from ``start`` on, assembled into the global array of
    ``size`` rows on rank 0 (None elsewhere)."""
    values = np.asarray(values)
    parts = comm.gather((int(start), values), root=0)
    if comm.rank != 0:
        return None
    out = np.empty((int(size),) + values.shape[1:], dtype=values.dtype)
    for s, a in parts:
        out[s:s + len(a)] = a
    return out


def gather_blocks(V, values, comm):
    """Global array (rank 0) of per-block data of the function space V (owned rows, global
    block order)."""
    im = V.dofmap.index_map
    return gather_ranges(im.local_range[0], np.asarray(values)[:im.size_local], im.size_global, comm)


def gather_rows(a, comm):
    """Every rank's rows of ``a`` concatenated in rank order on rank 0 (None elsewhere)."""
    parts = comm.gather(np.asarray(a), root=0)
    return np.concatenate(parts) if comm.rank == 0 else None


def on_rank0(comm, func, *args, errors=(OSError, ValueError, KeyError), wrap=RuntimeError):
    """Run ``func(*args)`` on rank 0 and broadcast its result to every rank.

    An exception of a type in ``errors`` on rank 0 is raised on every rank as ``wrap`` with
    the same one-line message (no rank is left waiting in a collective call).
    """
    out, err = None, None
    if comm.rank == 0:
        try:
            out = func(*args)
        except wrap as e:
            err = str(e)
        except errors as e:
            err = f"{type(e).__name__}: {e}"
    err = comm.bcast(err, root=0)
    if err:
        raise wrap(err)
    return comm.bcast(out, root=0)


# ------------------------------------------------------------------------------- writing
def json_default(o):
    """The JSON encoder's fallback for numpy scalars and arrays and paths."""
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")


def json_text(data, indent=2):
    """``data`` as JSON text (numpy values and paths included), ending with a newline."""
    return json.dumps(data, indent=indent, default=json_default) + "\n"


def atomic_write(path, write):
    """Create ``path`` through ``write(tmp_path)`` on a temporary file beside it, then rename
    (a reader never sees a half-written file; a failure leaves the old file). Not collective."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_text(path, text):
    """Write ``text`` to ``path`` atomically (not collective)."""
    def write(tmp):
        with open(tmp, "w") as fh:
            fh.write(text)
    atomic_write(path, write)


def write_json(path, data, comm, indent=2):
    """Atomic JSON write on rank 0 (collective: every rank waits for it)."""
    if comm.rank == 0:
        atomic_write_text(path, json_text(data, indent))
    comm.Barrier()
