"""The semi-smooth Newton on general gap rows: G x >= g.

Each step of the midpoint or backward Euler scheme with gap rows is the variational inequality

    G x >= g,   lam >= 0,   lam . (G x - g) = 0,   K x - b = G^T lam,

row i of G a linear functional of the displacement: against a rigid obstacle it reads the k = gdim
dofs of one node, G_i x = n_i . x_node (n_i the obstacle's unit normal there, so that G_i^T lam_i is
the force lam_i n_i on that node: :class:`NodeRows`, its coefficients given anew before every step);
a weighted (mortar) gap reads every dof of the contact facets around a vertex (:class:`MatrixRows`,
a distributed PETSc matrix fixed for the run). The axis-aligned bound x_c >= lb of
:class:`~.semismooth.SemismoothNewton` is the node row n_i = e_c.

As in its ``schur`` strategy, K is factorised once per run and the Newton systems are dense: with
x0 = K^-1 b (one solve per step) and the columns K^-1 e_j cached for every dof j an active row has
ever read (a node row whose normal turns costs no new solve), a Newton system on the active set A is
x = x0 + K^-1 G_A^T mu, with mu from the |A| x |A| SPD system

    (G_A K^-1 G_A^T) mu = g_A - G_A x0,

and mu is the multiplier. The active set is updated as in the primal-dual active set method
(Murty's rule against cycles).

**Krylov fallback.** When an active set needs more than ``max_columns`` cached columns (an active
zone of about max_columns / gdim nodes against an obstacle, fewer with weighted rows: a 3-D contact
zone at a fine level), the system is solved by conjugate gradients on the Schur complement instead,
each product S v = G_A K^-1 G_A^T v one solve with the factorisation (S is SPD for SPD K and rows of
full rank: the M formulation; the (U, V) block variant's K is not, and is refused there), then
x = x0 + K^-1 G_A^T mu by one more solve. The columns already cached stay for the smaller active sets.
CG stops at a residual of :data:`KRYLOV_RTOL` times the right-hand side's.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Optional, Union

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.solvers.base import MurtyRule, VIError
from sdm_dolfinx.solvers.factorisation import Factorisation
from sdm_dolfinx.solvers.options import instance_prefix, scoped_options, vi_tolerances
from sdm_dolfinx.solvers.schur import SCHUR_COLUMN_MEMORY, SCHUR_MAX_COLUMNS

Array = npt.NDArray[np.float64]

#: conjugate gradients on the Schur complement (the Krylov fallback) stop at this relative residual
KRYLOV_RTOL = 1e-12


class _Rows:
    """What the Newton loop needs of its rows (a subclass: where they read x): the cache of columns
    K^-1 e_j, G x, and the dense systems."""

    def __init__(self, K: PETSc.Mat, fac: Factorisation, m: int, max_columns: int) -> None:
        self.K, self.fac, self.comm = K, fac, K.getComm().tompi4py()
        self.g = np.zeros(m)
        self.max_columns = int(max_columns)
        self.its = 0
        self._slot: dict[int, int] = {}
        self._ncols = 0
        self._Zf: Optional[np.ndarray] = np.zeros((K.getLocalSize()[0], 0), order="F")
        self._rhs = K.createVecLeft()
        self._z = K.createVecRight()
        #: the rows' compliances 1/k (a penalty: lam = k (g - G x)_+), or None: the exact contact
        self.compliance: Optional[Array] = None
        #: K is SPD (the Krylov fallback's CG needs it); the last system was solved by it; its CG iterations
        self.spd = True
        self.krylov = False
        self.krylov_its = 0

    # the subclasses'
    def values(self, x: Array) -> Array:
        """G x at this rank's rows for the owned array x (collective)."""
        raise NotImplementedError

    def _entries(self, rows: npt.NDArray[np.int64]) -> tuple[np.ndarray, np.ndarray]:
        """(global column ids, values), each (len(rows), k), of the given local rows (zero-padded)."""
        raise NotImplementedError

    def _store(self, cols: np.ndarray, start: int) -> None:
        """Keep what the subclass needs of the new columns ``cols`` (n_local x k), slots start.."""
        raise NotImplementedError

    def _gz(self, slots: npt.NDArray[np.int64]) -> Array:
        """G K^-1 e_j at this rank's rows for the cached columns in ``slots`` (m x len(slots))."""
        raise NotImplementedError

    def _add_transpose(self, rows: npt.NDArray[np.int64], mu: Array, out: Array) -> None:
        """out += G_rows^T mu (owned entries; collective)."""
        raise NotImplementedError

    # shared
    def _ensure_columns(self, gids: list[int]) -> None:
        """Compute and cache K^-1 e_j for the ids not cached yet (collective, same list)."""
        missing = [j for j in gids if j not in self._slot]
        if not missing:
            return
        need = self._ncols + len(missing)
        if need > self.max_columns:
            raise VIError(f"the active contact zone needs {need} columns of K^-1 (at most {self.max_columns}) and "
                          f"the (U, V) block system's Schur complement is not SPD: no Krylov fallback (use mass "
                          f"'lumped')")
        cols = self.fac.solve_columns(missing)
        self.its += len(missing)
        if self._Zf is not None and need > self._Zf.shape[1]:
            cap = min(max(need, 2 * self._Zf.shape[1], 16), self.max_columns)
            fits = self.comm.allreduce(self._Zf.shape[0] * cap * 8 <= SCHUR_COLUMN_MEMORY, op=MPI.LAND)
            if fits:
                Zf = np.zeros((self._Zf.shape[0], cap), order="F")
                Zf[:, :self._ncols] = self._Zf[:, :self._ncols]
                self._Zf = Zf
            else:
                self._Zf = None
        if self._Zf is not None:
            self._Zf[:, self._ncols:need] = cols
        self._store(cols, self._ncols)
        for j, gid in enumerate(missing):
            self._slot[gid] = self._ncols + j
        self._ncols = need

    def start(self, x0: PETSc.Vec) -> None:
        self._x0 = x0
        self._gx0 = self.values(x0.array_r)

    def system(self, active: npt.NDArray[np.bool_]) -> tuple[Array, Array]:
        """(G x, lam) of the Newton system on ``active`` (collective), kept for :meth:`finish`."""
        comm, m = self.comm, len(self.g)
        rows = np.flatnonzero(active)
        ids_loc, vals_loc = self._entries(rows)
        ids, vals = comm.allgather(ids_loc), comm.allgather(vals_loc)
        k = max(a.shape[1] for a in ids) if ids else 1
        gA = np.concatenate([np.pad(a, ((0, 0), (0, k - a.shape[1])), constant_values=-1) for a in ids])
        cA = np.concatenate([np.pad(a, ((0, 0), (0, k - a.shape[1]))) for a in vals])
        nA = len(gA)
        if nA == 0:
            self._slots, self._pmu, self._rows, self._mu_local = np.zeros(0, np.int64), np.zeros(0), rows, np.zeros(0)
            return self._gx0.copy(), np.zeros(m)
        nz = cA != 0.0
        used = np.unique(gA[nz])
        self.krylov = self.spd and self._ncols + sum(j not in self._slot for j in used.tolist()) > self.max_columns
        if self.krylov:
            return self._krylov_system(rows)
        self._ensure_columns(used.tolist())
        slots = np.array([self._slot[j] for j in used.tolist()], dtype=np.int64)
        P = np.zeros((len(used), nA))                   # G_A^T in the basis of the used columns
        a_idx = np.nonzero(nz)
        np.add.at(P, (np.searchsorted(used, gA[a_idx]), a_idx[0]), cA[a_idx])
        GZ = self._gz(slots)
        S = np.vstack(comm.allgather(GZ[rows] @ P))
        if self.compliance is not None:         # a penalty: G_A x = g_A - mu / k_A
            S[np.diag_indices_from(S)] += np.concatenate(comm.allgather(self.compliance[rows]))
        r = np.concatenate(comm.allgather(self.g[rows] - self._gx0[rows]))
        mu = np.linalg.solve(S, r)
        pmu = P @ mu
        off = sum(len(p) for p in ids[:comm.rank])
        lam = np.zeros(m)
        lam[rows] = mu[off:off + len(rows)]
        self._slots, self._pmu, self._rows, self._mu_local = slots, pmu, rows, mu[off:off + len(rows)]
        return self._gx0 + GZ @ pmu, lam

    def _krylov_system(self, rows: npt.NDArray[np.int64]) -> tuple[Array, Array]:
        """:meth:`system` by CG on the Schur complement (the module's Krylov fallback); keeps
        K^-1 G_A^T mu for :meth:`finish`."""
        comm, m = self.comm, len(self.g)

        def spread(mu: Array) -> Array:             # K^-1 G_A^T mu (owned entries): one solve
            self._rhs.set(0.0)
            self._add_transpose(rows, mu, self._rhs.array)
            self.fac.solve(self._rhs, self._z)
            self.its += 1
            return self._z.array_r.copy()

        def apply(mu: Array) -> Array:
            out = self.values(spread(mu))[rows]
            return out + self.compliance[rows] * mu if self.compliance is not None else out

        def dot(a: Array, c: Array) -> float:
            return float(comm.allreduce(float(a @ c), op=MPI.SUM))

        r = self.g[rows] - self._gx0[rows]
        mu, p = np.zeros(len(rows)), r.copy()
        rr = dot(r, r)
        stop = KRYLOV_RTOL ** 2 * rr
        for _ in range(10 * comm.allreduce(len(rows), op=MPI.SUM) + 10):
            if rr <= stop:
                break
            q = apply(p)
            alpha = rr / dot(p, q)
            mu += alpha * p
            r -= alpha * q
            rr_new = dot(r, r)
            p = r + (rr_new / rr) * p
            rr = rr_new
            self.krylov_its += 1
        else:
            raise VIError(f"CG on the gap rows' Schur complement ({comm.allreduce(len(rows), op=MPI.SUM)} active rows) "
                          f"did not converge")
        self._kx = spread(mu)
        lam = np.zeros(m)
        lam[rows] = mu
        self._rows, self._mu_local = rows, mu
        return self._gx0 + self.values(self._kx), lam

    def finish(self, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """The full x of the accepted active set (the last :meth:`system`)."""
        if self.krylov:
            x.array[:] = self._x0.array_r + self._kx
            return
        if self._Zf is not None:
            out = self._x0.array_r.copy()
            for slot, v in zip(self._slots, self._pmu):
                out += v * self._Zf[:, slot]
            x.array[:] = out
        else:               # one more solve: K x = b + G_A^T mu
            b.copy(self._rhs)
            self._add_transpose(self._rows, self._mu_local, self._rhs.array)
            self.fac.solve(self._rhs, x)
            self.its += 1

    def destroy(self) -> None:
        self._rhs.destroy()
        self._z.destroy()


class NodeRows(_Rows):
    """Rows that read the owned dofs of one node each: G_i x = coef[i] . x[dofs[i]] (coefficients
    given before every solve: :meth:`set`). The columns are cached at the rows' dofs (Zt), so a
    normal that turns needs no product with the full columns."""

    def __init__(self, K, fac, dofs, max_columns):
        self.dofs = np.asarray(dofs, dtype=np.int32).reshape(len(dofs), -1) if len(dofs) else \
            np.zeros((0, 1), dtype=np.int32)
        m, k = self.dofs.shape
        super().__init__(K, fac, m, max_columns)
        self.coef = np.zeros((m, k))
        self.gd = (K.getOwnershipRange()[0] + self.dofs).astype(np.int64)
        self._Zt = np.zeros((m * k, 0))

    def set(self, coef, g):
        self.coef[:] = np.asarray(coef, dtype=float).reshape(self.coef.shape)
        self.g[:] = np.asarray(g, dtype=float).reshape(self.g.shape)

    def values(self, x):
        return np.einsum("ik,ik->i", self.coef, x[self.dofs]) if len(self.g) else np.zeros(0)

    def _entries(self, rows):
        return self.gd[rows], self.coef[rows]

    def _store(self, cols, start):
        need = start + cols.shape[1]
        if need > self._Zt.shape[1]:
            Zt = np.zeros((self._Zt.shape[0], max(need, 2 * self._Zt.shape[1], 16)))
            Zt[:, :start] = self._Zt[:, :start]
            self._Zt = Zt
        self._Zt[:, start:need] = cols[self.dofs.reshape(-1), :]

    def _gz(self, slots):
        m, k = self.dofs.shape
        return np.einsum("ik,iks->is", self.coef, self._Zt[:, slots].reshape(m, k, len(slots)))

    def _add_transpose(self, rows, mu, out):
        np.add.at(out, self.dofs[rows].reshape(-1), (self.coef[rows] * mu[:, None]).reshape(-1))

    def finish(self, b, x):
        super().finish(b, x)
        rows = self._rows
        if len(rows):       # one row per node (the rows share no dof): move along the row to g exactly
            c, xr = self.coef[rows], x.array[self.dofs[rows]]
            target = self.g[rows] if self.compliance is None else self.g[rows] - self.compliance[rows] * self._mu_local
            step = (target - np.einsum("ik,ik->i", c, xr)) / np.einsum("ik,ik->i", c, c)
            x.array[self.dofs[rows]] = xr + step[:, None] * c


class MatrixRows(_Rows):
    """Rows of a distributed PETSc matrix G fixed for the run (this rank's rows its local rows, K's
    column layout), with g given by :meth:`set`: a row may read dofs of other ranks. G K^-1 e_j is
    computed once per cached column (a sparse-dense product)."""

    def __init__(self, K, fac, G, max_columns):
        m = G.getLocalSize()[0]
        super().__init__(K, fac, m, max_columns)
        self.G = G
        ai, aj, av = G.getValuesCSR()
        self._ai, self._aj, self._av = np.asarray(ai), np.asarray(aj, dtype=np.int64), np.asarray(av)
        self._GZ = np.zeros((m, 0))
        self._xv, self._gv = G.createVecRight(), G.createVecLeft()

    def set(self, g):
        self.g[:] = np.asarray(g, dtype=float).reshape(self.g.shape)

    def values(self, x):
        self._xv.array[:] = x
        self.G.mult(self._xv, self._gv)
        return self._gv.array_r.copy()

    def _entries(self, rows):
        counts = self._ai[rows + 1] - self._ai[rows] if len(rows) else np.zeros(0, dtype=np.int64)
        k = int(counts.max(initial=1))
        ids, vals = np.full((len(rows), k), -1, dtype=np.int64), np.zeros((len(rows), k))
        for r, (i, n) in enumerate(zip(rows, counts)):
            ids[r, :n] = self._aj[self._ai[i]:self._ai[i] + n]
            vals[r, :n] = self._av[self._ai[i]:self._ai[i] + n]
        return ids, vals

    def _store(self, cols, start):
        nl, k = cols.shape
        D = PETSc.Mat().createDense([(nl, self.K.getSize()[0]), (None, k)], comm=self.K.getComm())
        D.setUp()
        D.getDenseArray()[:] = cols
        D.assemble()
        GZ = self.G.matMult(D)
        new = GZ.getDenseArray().copy()
        GZ.destroy(), D.destroy()
        need = start + k
        if need > self._GZ.shape[1]:
            grown = np.zeros((self._GZ.shape[0], max(need, 2 * self._GZ.shape[1], 16)))
            grown[:, :start] = self._GZ[:, :start]
            self._GZ = grown
        self._GZ[:, start:need] = new

    def _gz(self, slots):
        return self._GZ[:, slots]

    def _add_transpose(self, rows, mu, out):
        full = np.zeros(len(self.g))
        full[rows] = mu
        self._gv.array[:] = full
        self.G.multTranspose(self._gv, self._xv)
        out += self._xv.array_r

    def destroy(self):
        super().destroy()
        self._xv.destroy(), self._gv.destroy()


class GapNewton:
    """Primal-dual active set solver for the step VI with gap rows (see the module).

    Args:
        K: the step matrix (Dirichlet rows are identity rows).
        dofs: node rows: (m, k) owned local indices of x that each of this rank's m rows reads
            (coefficients and g given before each solve by :meth:`set_rows`); or None with ``G``.
        G: matrix rows: a PETSc matrix (this rank's rows, K's columns) fixed for the run (g by
            :meth:`set_rows` ``(None, g)``); or None with ``dofs``.
        symmetric_positive: K is SPD (M formulation); else the (U, V) block matrix.
        prefix: PETSc options prefix (None: a new ``sdm_<k>_``); ``vi_rtol``, ``vi_max_it``,
            ``vi_monitor`` as for the semi-smooth Newton (:func:`vi_tolerances`).
        options: default PETSc options of this instance.
        factor_matrix: a sparser matrix whose factorisation solves with K, or None.
        rtol: tolerance of the complementarity tests, relative to max|b|.
        max_it: Newton iterations before giving up.
        max_columns: the most columns K^-1 e_j cached (the largest active zone solved on them; beyond,
            the Krylov fallback); the option ``-<prefix>gap_max_columns`` overrides it.
        stiffness: a penalty instead of the exact contact: the rows' spring stiffnesses k (m,), the
            force lam = k (g - G x)_+ (:mod:`sdm_dolfinx.contact.penalty`); each Newton system is
            then (G_A K^-1 G_A^T + diag(1/k_A)) mu = g_A - G_A x0, as for the unit rows'
            :class:`~sdm_dolfinx.solvers.penalty.PenaltyNewton`.

    ``lam`` (m,) and ``active`` (m,) are those of the last solve; ``g`` the rows' right-hand sides.
    """

    def __init__(self, K: PETSc.Mat, dofs: Optional[npt.ArrayLike] = None, symmetric_positive: bool = True,
                 prefix: Optional[str] = None, options: Optional[Mapping[str, Any]] = None,
                 factor_matrix: Optional[PETSc.Mat] = None, rtol: float = 1e-10, max_it: int = 500,
                 max_columns: int = SCHUR_MAX_COLUMNS, G: Optional[PETSc.Mat] = None,
                 stiffness: Optional[npt.ArrayLike] = None) -> None:
        if (dofs is None) == (G is None):
            raise ValueError("GapNewton takes node rows (dofs) or a matrix G, one of them")
        self.K, self.comm = K, K.getComm().tompi4py()
        self.prefix, self.options = instance_prefix(self.comm, prefix), dict(options or {})
        self.spd, self.linear = symmetric_positive, "schur"
        with scoped_options(self.prefix, self.options, inherit=True) as scope:
            self.rtol, self.max_it, self.monitor = vi_tolerances(scope, rtol, max_it)
            # -<prefix>gap_max_columns N: the most columns of K^-1 cached (beyond: the Krylov fallback)
            max_columns = PETSc.Options().getInt(scope.prefix + "gap_max_columns", max_columns)
            if max_columns < 0:
                raise VIError(f"{scope.origin('gap_max_columns')}: {max_columns} is not an integer >= 0")
            self.fac = Factorisation(K, symmetric_positive, self.prefix + "factor_", aug=factor_matrix)
        self.rows: Union[NodeRows, MatrixRows] = (NodeRows(K, self.fac, dofs, max_columns) if G is None
                                                  else MatrixRows(K, self.fac, G, max_columns))
        self.rows.spd = bool(symmetric_positive)
        m = len(self.rows.g)
        if stiffness is not None:
            k = np.broadcast_to(np.asarray(stiffness, dtype=float), (m,))
            if not self.comm.allreduce(bool(np.all(np.isfinite(k) & (k > 0.0))), op=MPI.LAND):
                raise ValueError("the penalty's stiffnesses must be finite and > 0")
            self.rows.compliance = 1.0 / k
        self.num_constraints = self.comm.allreduce(m, op=MPI.SUM)
        self.lam, self.active = np.zeros(m), np.zeros(m, dtype=bool)
        # the Alart–Curnier scale r: the mean of K's diagonal at the dofs the rows read
        diag = K.getDiagonal()
        if isinstance(self.rows, NodeRows):
            read = self.rows.dofs.reshape(-1)
        else:
            read = np.unique(self.rows._aj) - K.getOwnershipRange()[0]
            read = read[(read >= 0) & (read < K.getLocalSize()[0])]
        dsum = self.comm.allreduce(float(np.sum(diag.array[read])), op=MPI.SUM)
        nread = self.comm.allreduce(len(read), op=MPI.SUM)
        self.r = dsum / nread if nread else 1.0
        diag.destroy()
        self._x0 = K.createVecRight()

    @property
    def g(self) -> Array:
        return self.rows.g

    @property
    def total_linear_its(self) -> int:
        """Solves with the factorisation so far (one per step, one per new column)."""
        return self.rows.its

    def set_rows(self, coef: Optional[npt.ArrayLike], g: npt.ArrayLike) -> None:
        """The rows of the next solve: node rows G_i x = coef[i] . x[dofs[i]] >= g[i]; matrix rows
        (coef None) G_i x >= g[i]."""
        if isinstance(self.rows, NodeRows):
            self.rows.set(coef, g)
        else:
            self.rows.set(g)

    def row_values(self, x: Array) -> Array:
        """G x at this rank's rows for the owned array ``x`` (collective for matrix rows)."""
        return self.rows.values(x)

    def imposed_gap(self, x: Array) -> float:
        """min over this rank's rows of G x - g (collective for matrix rows: every rank calls it)."""
        return float(np.min(self.row_values(x) - self.g, initial=np.inf))

    def solve(self, b: PETSc.Vec, x: PETSc.Vec) -> dict[str, Any]:
        """Solve the step VI for the right-hand side b into x (see the module); returns
        ``{"its", "n_active"}``. Raises VIError (no convergence, a contact zone too large)."""
        rows = self.rows
        with scoped_options(self.prefix, self.options, inherit=True):
            self.fac.solve(b, self._x0)
        rows.its += 1
        rows.start(self._x0)
        scale = max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        tol_lam = self.rtol * scale
        tol_x = tol_lam / self.r
        active = self.active.copy()
        first = self.comm.exscan(len(rows.g)) or 0
        murty = MurtyRule(first + np.arange(len(rows.g)), self.comm)
        for it in range(1, self.max_it + 1):
            gx, lam = rows.system(active)
            lam = np.where(active, lam, 0.0)
            infeasible = np.where(active, lam < -tol_lam, gx < rows.g - tol_x)
            n_inf = self.comm.allreduce(int(np.count_nonzero(infeasible)), op=MPI.SUM)
            self.lam, self.active = lam, active
            if self.monitor:
                n_act = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
                if self.comm.rank == 0:
                    print(f"  {it:3d} semi-smooth Newton (gap rows): {n_act} active, {n_inf} infeasible", flush=True)
            if n_inf == 0:
                rows.finish(b, x)
                return {"its": it, "n_active": self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)}
            one = murty.single(n_inf, infeasible)
            active = active ^ (infeasible if one is None else one)
        raise VIError(f"semi-smooth Newton (gap rows) did not converge in {self.max_it} iterations "
                      f"({n_inf} rows still infeasible)")

    def destroy(self) -> None:
        self._x0.destroy()
        self.rows.destroy()
        self.fac.destroy()
