"""The gap of a state to the bound: min of u_c - bound over the constrained vertices or over every
dof of the constrained boundary (collective), from the Discretisation alone.

The Integrator, the time series and the observers' :class:`~sdm_dolfinx.run.observe.State` all
measure it here. ``u`` is the owned part of a W^h vector as an array (``U.array_r``). Against a
Problem's obstacles the gap is the signed distance phi(a_i + u_i, t) to the nearest obstacle at the
time ``t`` of the state (:mod:`.obstacle_rows`), not linearised.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.method.dofs import where_least

if TYPE_CHECKING:
    from sdm_dolfinx.method.discretisation import Discretisation


def _rows(d):
    """The Discretisation's gap rows that measure true distances (obstacles, bodies), or None."""
    return d.obstacle_rows if d.obstacle_rows is not None else getattr(d, "body_rows", None)


def vertex_gap(discretisation: Discretisation, u: npt.NDArray[np.float64], t: float = 0.0) -> float:
    """min over the constrained vertices of u_c - bound, reduced over the ranks (+inf without any)."""
    d = discretisation
    rows = _rows(d)
    if rows is not None:
        return rows.gap(u, t)
    return d.comm.allreduce(float(np.min(u[d.cdofs] - d.lb, initial=np.inf)), op=MPI.MIN)


def boundary_gap(discretisation: Discretisation, u: npt.NDArray[np.float64], t: float = 0.0) -> float:
    """min over every dof of W^h on the constrained boundary (P2 mid-edge nodes included) of
    u_c - bound, reduced over the ranks (+inf without such dofs)."""
    d = discretisation
    rows = _rows(d)
    if rows is not None:
        return rows.gap(u, t, boundary=True)
    return d.comm.allreduce(float(np.min(u[d.bdofs] - d.blb, initial=np.inf)), op=MPI.MIN)


def boundary_gap_where(discretisation: Discretisation, u: npt.NDArray[np.float64],
                       t: float = 0.0) -> npt.NDArray[np.float64]:
    """The coordinates (gdim,) of the dof where :func:`boundary_gap` is reached (collective)."""
    d = discretisation
    rows = _rows(d)
    if rows is not None:
        return rows.where(u, t)
    x = where_least(d.comm, u[d.bdofs] - d.blb, d.bx)
    return x[:d.problem.mesh.geometry.dim]


def displacement_spread(discretisation: Discretisation, u: npt.NDArray[np.float64]) -> float:
    """max - min over every owned dof of W^h of the bounded component u_c, reduced over the ranks
    (0.0 without dofs): the run's displacement scale in the direction of the constraint, a rigid
    translation excluded (a block pushed down by d at its top while its bottom rests: d). Against
    obstacles, whose normals turn, the largest such spread over the components."""
    d = discretisation
    bs = d.W.dofmap.index_map_bs
    comps = range(bs) if _rows(d) is not None else [d.problem.constraint_component or 0]
    ext = np.array([v for c in comps for v in (np.max(u[c::bs], initial=-np.inf), -np.min(u[c::bs], initial=np.inf))])
    d.comm.Allreduce(MPI.IN_PLACE, ext, op=MPI.MAX)
    spreads = ext[0::2] + ext[1::2]
    return float(np.max(spreads)) if np.all(np.isfinite(ext)) else 0.0
