"""Checks of a Problem's mesh before anything is assembled: cells of zero measure (their mass and
stiffness would be singular: the run failed at step 0 with a NaN energy)."""
from __future__ import annotations

from typing import Any, Optional

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat


#: a simplex whose measure is below this times its longest edge from its first vertex to the
#: power of its dimension counts as degenerate (round-off of an exactly flat cell is ~1e-16)
DEGENERATE_RTOL = 1e-12


def degenerate_cells(msh: Any) -> Optional[str]:
    """'N of its M cells have zero measure (one at (x, y))' for a simplex mesh with flat cells
    (their mass and stiffness are singular: the run fails at step 0 with a NaN energy), else
    None. Collective; checks the straight simplex of each cell's vertices (curved cells too)."""
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    comm = msh.comm
    ncells = msh.topology.index_map(tdim).size_local
    nodes = compat.mesh_geometry_dofmap(msh)
    simplex = compat.cell_name(msh) in ("interval", "triangle", "tetrahedron")
    x = msh.geometry.x[:, :gdim]
    bad = np.zeros(0, dtype=np.int64)
    if simplex and ncells:
        v = x[nodes[:ncells, :tdim + 1]]                       # (cells, tdim + 1, gdim): the vertices
        J = v[:, 1:, :] - v[:, :1, :]                          # (cells, tdim, gdim)
        if tdim == gdim:
            measure = np.abs(np.linalg.det(J))
        else:
            measure = np.sqrt(np.maximum(np.linalg.det(np.einsum("cij,ckj->cik", J, J)), 0.0))
        scale = np.max(np.linalg.norm(J, axis=2), axis=1) ** tdim
        bad = np.flatnonzero(~(measure > DEGENERATE_RTOL * scale))
    count, total = comm.allreduce(len(bad), op=MPI.SUM), comm.allreduce(ncells, op=MPI.SUM)
    if not count:
        return None
    where = [x[nodes[bad[0], :tdim + 1]].mean(axis=0) if len(bad) else None]
    where = next(w for w in comm.allgather(where[0]) if w is not None)
    return (f"{count} of its {total} cells have zero measure (one at ({', '.join(f'{c:.6g}' for c in where)})): "
            f"its mass and stiffness would be singular")
