"""The gap rows of :mod:`.gap_newton` (where they read x): node rows (:class:`NodeRows`, one node each,
coefficients given anew before every step: the obstacles), matrix rows (:class:`MatrixRows`, a
distributed PETSc matrix fixed for the run: the weighted gap) and surface rows (:class:`SurfaceRows`,
ids and coefficients given anew before every step among a fixed set of dofs: contact between bodies), with what the Newton loop needs of both
(:class:`_Rows`): the cache of columns K^-1 e_j, G x, the dense systems on the cached columns, and the
Krylov fallback (:mod:`.gap_krylov`) beyond them."""
from __future__ import annotations

from typing import Optional

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.solvers import gap_krylov
from sdm_dolfinx.solvers.base import VIError
from sdm_dolfinx.solvers.factorisation import Factorisation
from sdm_dolfinx.solvers.repeated_rows import solve_repeated
from sdm_dolfinx.solvers.schur import SCHUR_COLUMN_MEMORY

Array = npt.NDArray[np.float64]


def active_multipliers(S: Array, r: Array) -> Array:
    """The multipliers mu of S mu = r, S = G_A K^-1 G_A^T (the same on every rank), active rows that repeat
    others allowed (:func:`~.repeated_rows.solve_repeated`: the minimum-norm mu, each repeated row's force
    split equally whatever the rows' order; repeated rows asking for other gaps: VIError)."""
    return solve_repeated(S, r, "the active contact rows are linearly dependent and ask for different gaps (two "
                                "constraints holding the same dofs against each other with different bounds): no "
                                "step satisfies both")


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
        #: K is SPD (the Krylov fallback is built for it); the last system was solved by it; its CG iterations
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
            raise VIError(f"the active contact zone needs {need} columns of K^-1 (at most {self.max_columns}), and "
                          f"the Krylov fallback is not built for the (U, V) block system: use mass 'lumped'")
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
        mu = active_multipliers(S, r)
        pmu = P @ mu
        off = sum(len(p) for p in ids[:comm.rank])
        lam = np.zeros(m)
        lam[rows] = mu[off:off + len(rows)]
        self._slots, self._pmu, self._rows, self._mu_local = slots, pmu, rows, mu[off:off + len(rows)]
        return self._gx0 + GZ @ pmu, lam

    def _krylov_system(self, rows: npt.NDArray[np.int64]) -> tuple[Array, Array]:
        """:meth:`system` by CG on the Schur complement (:mod:`.gap_krylov`); keeps K^-1 G_A^T mu for
        :meth:`finish`."""
        self._kx, mu, its = gap_krylov.solve(self, rows)
        self.krylov_its += its
        lam = np.zeros(len(self.g))
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


class SurfaceRows(_Rows):
    """Rows that read any of a fixed set of global dofs ``read`` (contact surfaces: a row reads its
    slave node and the nodes of a master facet, which may be another rank's), with ids and coefficients
    given anew before every solve (:meth:`set`). The columns K^-1 e_j are cached at the ``read`` dofs and
    replicated on every rank (len(read) numbers per column), so a row that moves to another facet
    needs no product with the full columns."""

    def __init__(self, K, fac, read, m, max_columns):
        super().__init__(K, fac, m, max_columns)
        self.read = np.asarray(read, dtype=np.int64)
        lo, hi = K.getOwnershipRange()
        self._own = (self.read >= lo) & (self.read < hi)
        self._local = (self.read[self._own] - lo).astype(np.int64)
        self.ids = np.zeros((m, 1), dtype=np.int64)
        self.coef = np.zeros((m, 1))
        self._pos = np.zeros((m, 1), dtype=np.int64)
        self._Zr = np.zeros((len(self.read), 0))

    def set(self, rows, g):
        ids, coef = rows
        self.ids, self.coef = np.asarray(ids, dtype=np.int64), np.asarray(coef, dtype=float)
        self._pos = np.searchsorted(self.read, self.ids)
        #: the rows with a coefficient (a row without one holds nothing this step: never active)
        self.alive = np.any(self.coef != 0.0, axis=1)
        if not self.comm.allreduce(bool(np.all(self.read[np.minimum(self._pos, len(self.read) - 1)] == self.ids)),
                                   op=MPI.LAND):
            raise VIError("a contact row reads a dof outside the contact surfaces' (internal error)")
        self.g[:] = np.asarray(g, dtype=float).reshape(self.g.shape)

    def _gathered(self, local: np.ndarray) -> np.ndarray:
        """The ``read`` rows of the owned array(s) ``local`` (n_local or n_local x k), on every rank."""
        out = np.zeros((len(self.read),) + local.shape[1:])
        out[self._own] = local[self._local]
        self.comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
        return out

    def values(self, x):
        xr = self._gathered(np.asarray(x))
        return np.einsum("ik,ik->i", self.coef, xr[self._pos]) if len(self.g) else np.zeros(0)

    def _entries(self, rows):
        return self.ids[rows], self.coef[rows]

    def _store(self, cols, start):
        new = self._gathered(np.ascontiguousarray(cols))
        need = start + cols.shape[1]
        if need > self._Zr.shape[1]:
            grown = np.zeros((len(self.read), max(need, 2 * self._Zr.shape[1], 16)))
            grown[:, :start] = self._Zr[:, :start]
            self._Zr = grown
        self._Zr[:, start:need] = new

    def _gz(self, slots):
        if not len(self.g):
            return np.zeros((0, len(slots)))
        return np.einsum("ik,iks->is", self.coef, self._Zr[:, slots][self._pos])

    def _add_transpose(self, rows, mu, out):
        c = np.zeros(len(self.read))
        np.add.at(c, self._pos[rows].reshape(-1), (self.coef[rows] * mu[:, None]).reshape(-1))
        self.comm.Allreduce(MPI.IN_PLACE, c, op=MPI.SUM)
        out[self._local] += c[self._own]
