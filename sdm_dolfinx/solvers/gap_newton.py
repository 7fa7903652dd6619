"""The semi-smooth Newton on general gap rows: G x >= g, one row per contact point.

Each step of the midpoint or backward Euler scheme against rigid obstacles is the variational
inequality

    G x >= g,   lam >= 0,   lam . (G x - g) = 0,   K x - b = G^T lam,

where row i of G reads the k = gdim displacement dofs of one node, G_i x = n_i . x_node (n_i the
obstacle's unit normal there), so that G_i^T lam_i is the force lam_i n_i on that node. The
axis-aligned bound x_c >= lb of :class:`~.semismooth.SemismoothNewton` is the case n_i = e_c.

As in its ``schur`` strategy, K is factorised once per run and the Newton systems are dense: with
x0 = K^-1 b (one solve per step) and the columns K^-1 e_j cached for every dof j an active row has
ever read (so that a row whose normal changes from step to step costs no new solve), a Newton
system on the active set A is x = x0 + K^-1 G_A^T mu, with mu from the |A| x |A| SPD system

    (G_A K^-1 G_A^T) mu = g_A - G_A x0,

and mu is the multiplier. The active set is updated as in the primal-dual active set method
(Murty's rule against cycles). There is no Krylov fallback: more than ``max_columns`` cached
columns (an active contact zone of more than max_columns / gdim nodes) is refused in one line.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Optional

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.solvers.base import MurtyRule, VIError
from sdm_dolfinx.solvers.factorisation import Factorisation
from sdm_dolfinx.solvers.options import instance_prefix, scoped_options, vi_tolerances
from sdm_dolfinx.solvers.schur import SCHUR_COLUMN_MEMORY, SCHUR_MAX_COLUMNS


class GapNewton:
    """Primal-dual active set solver for the step VI with gap rows (see the module).

    Args:
        K: the step matrix (Dirichlet rows are identity rows).
        dofs: (m, k) owned local indices of x that each of this rank's m rows reads.
        symmetric_positive: K is SPD (M formulation); else the (U, V) block matrix.
        prefix: PETSc options prefix (None: a new ``sdm_<k>_``); options as for the semi-smooth Newton
            (``snes_max_it``, ``snes_monitor``, ``snes_rtol`` ...) through :func:`vi_tolerances`.
        options: default PETSc options of this instance.
        factor_matrix: a sparser matrix whose factorisation solves with K, or None.
        rtol: tolerance of the complementarity tests, relative to max|b|.
        max_it: Newton iterations before giving up.
        max_columns: the most columns K^-1 e_j cached (the largest active zone it solves).

    The rows (their coefficients and right-hand sides) are given before each solve by
    :meth:`set_rows`; ``lam`` (m,) and ``active`` (m,) are those of the last solve.
    """

    def __init__(self, K: PETSc.Mat, dofs: npt.ArrayLike, symmetric_positive: bool = True,
                 prefix: Optional[str] = None, options: Optional[Mapping[str, Any]] = None,
                 factor_matrix: Optional[PETSc.Mat] = None, rtol: float = 1e-10, max_it: int = 500,
                 max_columns: int = SCHUR_MAX_COLUMNS) -> None:
        self.K, self.comm = K, K.getComm().tompi4py()
        self.dofs = np.asarray(dofs, dtype=np.int32).reshape(len(dofs), -1) if len(dofs) else \
            np.zeros((0, 1), dtype=np.int32)
        m, k = self.dofs.shape
        self.num_constraints = self.comm.allreduce(m, op=MPI.SUM)
        self.coef, self.g = np.zeros((m, k)), np.zeros(m)
        self.lam, self.active = np.zeros(m), np.zeros(m, dtype=bool)
        self.prefix, self.options = instance_prefix(self.comm, prefix), dict(options or {})
        self.spd, self.max_columns, self.linear = symmetric_positive, int(max_columns), "schur"
        with scoped_options(self.prefix, self.options, inherit=True) as scope:
            self.rtol, self.max_it, self.monitor = vi_tolerances(scope, rtol, max_it)
            self.fac = Factorisation(K, symmetric_positive, self.prefix + "factor_", aug=factor_matrix)
        diag = K.getDiagonal()
        dsum = self.comm.allreduce(float(np.sum(diag.array[self.dofs])), op=MPI.SUM)
        self.r = dsum / (self.num_constraints * k) if self.num_constraints else 1.0    # Alart–Curnier r
        diag.destroy()
        self.its = 0
        self.gd = (K.getOwnershipRange()[0] + self.dofs).astype(np.int64)        # global ids, (m, k)
        self._slot: dict[int, int] = {}
        self._Zt = np.zeros((m * k, 0))                # cached columns at the rows' dofs (row-major m x k)
        self._Zf: Optional[np.ndarray] = np.zeros((K.getLocalSize()[0], 0), order="F")
        self._ncols = 0
        self._x0 = K.createVecRight()
        self._rhs = K.createVecLeft()

    @property
    def total_linear_its(self) -> int:
        """Solves with the factorisation so far (one per step, one per new column)."""
        return self.its

    def set_rows(self, coef: npt.ArrayLike, g: npt.ArrayLike) -> None:
        """The rows of the next solve: G_i x = coef[i] . x[dofs[i]] >= g[i]."""
        self.coef[:] = np.asarray(coef, dtype=float).reshape(self.coef.shape)
        self.g[:] = np.asarray(g, dtype=float).reshape(self.g.shape)

    def row_values(self, x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """G x at this rank's rows for the owned array ``x``."""
        return np.einsum("ik,ik->i", self.coef, x[self.dofs]) if len(self.g) else np.zeros(0)

    def _ensure_columns(self, gids: list[int]) -> None:
        """Compute and cache K^-1 e_j for the ids not cached yet (collective, same list)."""
        missing = [j for j in gids if j not in self._slot]
        if not missing:
            return
        need = self._ncols + len(missing)
        if need > self.max_columns:
            raise VIError(f"the active contact zone needs {need} columns of K^-1 (at most {self.max_columns}: "
                          f"about {self.max_columns // max(self.dofs.shape[1], 1)} active nodes against an obstacle)")
        cols = self.fac.solve_columns(missing)
        self.its += len(missing)
        if need > self._Zt.shape[1]:
            cap = min(max(need, 2 * self._Zt.shape[1], 16), self.max_columns)
            Zt = np.zeros((self._Zt.shape[0], cap))
            Zt[:, :self._ncols] = self._Zt[:, :self._ncols]
            self._Zt = Zt
            fits = self.comm.allreduce(self.K.getLocalSize()[0] * cap * 8 <= SCHUR_COLUMN_MEMORY, op=MPI.LAND)
            if self._Zf is not None and fits:
                Zf = np.zeros((self._Zf.shape[0], cap), order="F")
                Zf[:, :self._ncols] = self._Zf[:, :self._ncols]
                self._Zf = Zf
            else:
                self._Zf = None
        self._Zt[:, self._ncols:need] = cols[self.dofs.reshape(-1), :]
        if self._Zf is not None:
            self._Zf[:, self._ncols:need] = cols
        for j, gid in enumerate(missing):
            self._slot[gid] = self._ncols + j
        self._ncols = need

    def _system(self, active):
        """(G x, lam) of the Newton system on ``active`` (collective), keeping (slots, P mu) for :meth:`_finish`."""
        comm, (m, k) = self.comm, self.dofs.shape
        rows = np.flatnonzero(active)
        ids = comm.allgather(self.gd[rows])
        cfs = comm.allgather(self.coef[rows])
        gA = np.concatenate(ids) if ids else np.zeros((0, k), dtype=np.int64)
        cA = np.concatenate(cfs) if cfs else np.zeros((0, k))
        nA = len(gA)
        if nA == 0:
            self._slots, self._pmu, self._mu_local = np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
            return self._gx0.copy(), np.zeros(m)
        used = np.unique(gA[cA != 0.0]) if np.any(cA != 0.0) else np.unique(gA)
        self._ensure_columns(used.tolist())
        slots = np.array([self._slot[j] for j in used.tolist()], dtype=np.int64)
        where = {j: s for s, j in enumerate(used.tolist())}
        P = np.zeros((len(used), nA))                   # G_A^T in the basis of the used columns
        for a in range(nA):
            for c in range(k):
                if cA[a, c] != 0.0:
                    P[where[int(gA[a, c])], a] += cA[a, c]
        Zt = self._Zt[:, slots].reshape(m, k, len(slots))
        GZ = np.einsum("ik,iks->is", self.coef, Zt)     # G K^-1 at this rank's rows, used columns
        S = np.vstack(comm.allgather(GZ[rows] @ P))
        r = np.concatenate(comm.allgather(self.g[rows] - self._gx0[rows]))
        mu = np.linalg.solve(S, r)
        pmu = P @ mu
        off = sum(len(p) for p in ids[:comm.rank])
        lam = np.zeros(m)
        lam[rows] = mu[off:off + len(rows)]
        self._slots, self._pmu, self._mu_local = slots, pmu, mu[off:off + len(rows)]
        return self._gx0 + GZ @ pmu, lam

    def _finish(self, b, x, active):
        """The full x of the accepted active set, each active row then held exactly."""
        if self._Zf is not None:
            out = self._x0.array_r.copy()
            for slot, v in zip(self._slots, self._pmu):
                out += v * self._Zf[:, slot]
            x.array[:] = out
        else:               # one more solve: K x = b + G_A^T mu
            b.copy(self._rhs)
            rows = np.flatnonzero(active)
            np.add.at(self._rhs.array, self.dofs[rows].reshape(-1), (self.coef[rows] * self._mu_local[:, None]).reshape(-1))
            self.fac.solve(self._rhs, x)
            self.its += 1
        rows = np.flatnonzero(active)
        if len(rows):       # one row per node (the rows share no dof): move along the row to g exactly
            c = self.coef[rows]
            xr = x.array[self.dofs[rows]]
            step = (self.g[rows] - np.einsum("ik,ik->i", c, xr)) / np.einsum("ik,ik->i", c, c)
            x.array[self.dofs[rows]] = xr + step[:, None] * c

    def solve(self, b: PETSc.Vec, x: PETSc.Vec) -> dict[str, Any]:
        """Solve the step VI for the right-hand side b into x (see the module); returns
        ``{"its", "n_active"}``. Raises VIError (no convergence, a contact zone too large)."""
        with scoped_options(self.prefix, self.options, inherit=True):
            self.fac.solve(b, self._x0)
        self.its += 1
        self._gx0 = self.row_values(self._x0.array_r)
        scale = max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        tol_lam = self.rtol * scale
        tol_x = tol_lam / self.r
        active = self.active.copy()
        first = self.comm.exscan(len(self.g)) or 0
        murty = MurtyRule(first + np.arange(len(self.g)), self.comm)
        for it in range(1, self.max_it + 1):
            gx, lam = self._system(active)
            lam = np.where(active, lam, 0.0)
            infeasible = np.where(active, lam < -tol_lam, gx < self.g - tol_x)
            n_inf = self.comm.allreduce(int(np.count_nonzero(infeasible)), op=MPI.SUM)
            self.lam, self.active = lam, active
            if self.monitor:
                n_act = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
                if self.comm.rank == 0:
                    print(f"  {it:3d} semi-smooth Newton (gap rows): {n_act} active, {n_inf} infeasible", flush=True)
            if n_inf == 0:
                self._finish(b, x, active)
                return {"its": it, "n_active": self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)}
            one = murty.single(n_inf, infeasible)
            active = active ^ (infeasible if one is None else one)
        raise VIError(f"semi-smooth Newton (gap rows) did not converge in {self.max_it} iterations "
                      f"({n_inf} rows still infeasible)")

    def destroy(self) -> None:
        self._x0.destroy()
        self._rhs.destroy()
        self.fac.destroy()
