"""The gap-row Newton's Krylov fallback (:mod:`.gap_newton`): a Newton system on an active set too large for
the cached columns of K^-1, solved by conjugate gradients on its Schur complement

    (G_A K^-1 G_A^T + C_A) mu = g_A - G_A x0,

each product one solve with the factorisation (C the penalty's compliances, or 0), then K^-1 G_A^T mu by
one more solve. For SPD K and rows of full rank the operator is SPD."""
from __future__ import annotations

from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.solvers.base import VIError

Array = npt.NDArray[np.float64]

#: conjugate gradients on the Schur complement stop at this relative residual
KRYLOV_RTOL = 1e-12


def solve(rows_obj: Any, rows: npt.NDArray[np.int64]) -> tuple[Array, Array, int]:
    """(K^-1 G_A^T mu (owned entries), mu (this rank's active rows), CG iterations) for the active rows
    ``rows`` of the gap rows ``rows_obj`` (a :class:`~.gap_rows._Rows` after its ``start``; collective)."""
    r_, comm = rows_obj, rows_obj.comm

    def spread(mu: Array) -> Array:             # K^-1 G_A^T mu: one solve
        r_._rhs.set(0.0)
        r_._add_transpose(rows, mu, r_._rhs.array)
        r_.fac.solve(r_._rhs, r_._z)
        r_.its += 1
        return np.asarray(r_._z.array_r).copy()

    def apply(mu: Array) -> Array:
        out = r_.values(spread(mu))[rows]
        return out + r_.compliance[rows] * mu if r_.compliance is not None else out

    def dot(a: Array, c: Array) -> float:
        return float(comm.allreduce(float(a @ c), op=MPI.SUM))

    res = r_.g[rows] - r_._gx0[rows]
    mu, p = np.zeros(len(rows)), res.copy()
    rr = dot(res, res)
    stop = KRYLOV_RTOL ** 2 * rr
    n = comm.allreduce(len(rows), op=MPI.SUM)
    its = 0
    for _ in range(10 * n + 10):
        if rr <= stop:
            break
        q = apply(p)
        alpha = rr / dot(p, q)
        mu += alpha * p
        res -= alpha * q
        rr_new = dot(res, res)
        p = res + (rr_new / rr) * p
        rr = rr_new
        its += 1
    else:
        raise VIError(f"CG on the gap rows' Schur complement ({n} active rows) did not converge")
    return spread(mu), mu, its
