"""Probes: the displacement at a point and the contact stress at the constrained vertex nearest
to it, reduced over ranks (every rank gets the value)."""
from __future__ import annotations

from typing import TYPE_CHECKING

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
from dolfinx import fem

from sdm_dolfinx import compat

if TYPE_CHECKING:
    from petsc4py import PETSc


class PointProbe:
    """Value of a W-function at a point, on every rank (the lowest rank owning it evaluates)."""

    def __init__(self, V, point, component=None):
        msh = V.mesh
        self.comm = msh.comm
        x = np.zeros((1, 3))
        x[0, :len(point)] = point
        self.x = x
        cells = compat.colliding_cells(msh, compat.bounding_box_tree(msh), x).links(0)
        nowned = msh.topology.index_map(msh.topology.dim).size_local
        cells = cells[cells < nowned]
        rank = self.comm.rank if len(cells) else self.comm.size
        self.owner = self.comm.allreduce(rank, op=MPI.MIN)
        if self.owner == self.comm.size:
            raise ValueError(f"probe point {tuple(point)} lies outside the mesh")
        self.cell = cells[:1]
        self.component = component
        self.f = fem.Function(V)

    def __call__(self, vec: PETSc.Vec) -> float:
        """Evaluate the W-vector ``vec`` (owned entries) at the probe point."""
        n = len(vec.array)
        self.f.x.array[:n] = vec.array
        self.f.x.scatter_forward()
        val = 0.0
        if self.comm.rank == self.owner:
            v = self.f.eval(self.x, self.cell).reshape(-1)
            val = float(v[self.component or 0])
        return self.comm.allreduce(val, op=MPI.SUM)


class ConstraintProbe:
    """The constrained vertex nearest to a point: its stress lam_i / m_i (m_i the lumped measure)."""

    def __init__(self, discretisation, point):
        self.comm = discretisation.comm
        p = np.zeros(3)
        p[:len(point)] = point
        d = np.linalg.norm(discretisation.cx.T - p[None, :], axis=1) if discretisation.cx.shape[1] else np.zeros(0)
        dmin = float(d.min()) if d.size else np.inf
        best = self.comm.allreduce((dmin, self.comm.rank), op=MPI.MINLOC)
        self.owner = best[1]
        self.index = int(np.argmin(d)) if (self.comm.rank == self.owner and d.size) else -1
        x = discretisation.cx[:, self.index].copy() if self.index >= 0 else np.zeros(3)
        self.vertex = self.comm.allreduce(x, op=MPI.SUM)
        self.measure = discretisation.cmeasure

    def __call__(self, lam: npt.NDArray[np.float64]) -> float:
        val = lam[self.index] / self.measure[self.index] if self.index >= 0 else 0.0
        return self.comm.allreduce(float(val), op=MPI.SUM)

    def at(self, values: npt.NDArray[np.float64]) -> float:
        """``values`` (one per owned constrained vertex) at the probe's vertex, on every rank."""
        val = values[self.index] if self.index >= 0 else 0.0
        return self.comm.allreduce(float(val), op=MPI.SUM)

    def at_components(self, values: npt.NDArray[np.float64], k: int) -> list[float]:
        """The row of ``values`` (m x k: k per owned constrained vertex) at the probe's vertex, on
        every rank."""
        val = np.asarray(values[self.index], dtype=float).reshape(k) if self.index >= 0 else np.zeros(k)
        return self.comm.allreduce(val, op=MPI.SUM)
