"""The Newton systems of the frictional step solver: K plus constraints on the contact dofs,
solved by a small dense system on cached columns of K^-1 (the ``schur`` idea of
:mod:`sdm_dolfinx.solvers.schur`, extended to prescribed and coupled reactions).

A Newton iteration of :class:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton` fixes, on the
2m contact dofs (m normal, then m tangential ones), three kinds of conditions:

* a *fixed* dof j has a prescribed value x_j = target_j (active normal: lb; stick
  tangential: xref) and an unknown reaction r_j;
* a *forced* dof j has a prescribed reaction r_j = a_j + c_j r_p(j) (slip tangential:
  a_j = sigma_j s_j for Tresca, c_j = sigma_j mu_j for Coulomb, p(j) the normal dof of the
  same vertex, fixed then);
* every other dof is free (r_j = 0).

With x0 = K^-1 b (once per step) and Z = K^-1 E (columns K^-1 e_j, each solved once per run
and cached), K x - b = r gives x = x0 + Z_J a + (Z_F + Z_J D) r_F, D_{j p(j)} = c_j, so the
fixed values are the dense |F| x |F| system (Z_FF + Z_FJ D) r_F = target_F - x0_F - Z_FJ a.
For Tresca it is a principal block of K^-1 (SPD for SPD K); for Coulomb the Z_FJ D term makes
it non-symmetric: it is solved by LU (numpy's LAPACK gesv) in both cases, which is cheap
at these sizes (|F| <= 2m) and needs no symmetry; a singular system (possible for Coulomb
with a large friction coefficient, where the discrete problem may lose uniqueness) raises
:class:`~sdm_dolfinx.solvers.base.VIError`.

In parallel every rank owns whole vertices (both dofs of a vertex on one rank, as dolfinx's
blocked dofmaps do), keeps its rows of the cached columns, and the dense system is gathered
on every rank (the pattern of :class:`~sdm_dolfinx.solvers.schur.SchurComplement`).

**Frames** (:meth:`FrictionSystem.set_frames`: friction against a curved or tilted obstacle). The
contact dofs are then a node's gdim Cartesian dofs (component-major, as above) and the unknowns
their components y_i = Q_i x_i in an orthonormal frame per node (row 0 the obstacle's normal, then
the tangents), given anew every step: the normal "dof" of a node is n_i . x_i. Everything above
holds in the frame: a condition's column is K^-1 Q_i^T e_k = sum_c Q_ikc K^-1 e_(i,c), a
combination of the node's cached Cartesian columns, so a frame that turns costs no new solve; its
rows are rotated the same way, and the reactions go back as Q_i^T r_i. Without frames (None) the
contact dofs are the unknowns themselves and nothing is rotated (the axis-aligned obstacle).
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.solvers.repeated_rows import solve_repeated
from sdm_dolfinx.solvers.schur import SCHUR_COLUMN_MEMORY


#: :meth:`FrictionSystem.finish` sums at most this many cached columns, else solves once
#: more. Measured at 50k dofs (P1 elasticity, CHOLMOD, 1 rank): ~350 columns summed in
#: 16 ms, one solve 10 ms (a2 = 0.01) to 4 ms (a2 = 100, mass-dominated), so the break-even
#: is ~100-200 columns. (The ``schur`` strategy's product Z[:, slots] @ mu copies the
#: columns first: 37 ms for ~400 columns.)
FINISH_MAX_AXPY = 100


class ColumnCache:
    """Columns K^-1 e_g of the contact dofs, solved on first use and kept for the run: their
    rows at this rank's contact dofs (``Zc``, 2m x 2m numbers at most) and, while they take
    less than :data:`~sdm_dolfinx.solvers.schur.SCHUR_COLUMN_MEMORY` per rank, all their
    local rows (``Zt``, one contiguous row per column). ``its`` counts the solves with the
    factorisation."""

    def __init__(self, fac, cdofs, n_local):
        self.fac, self.cdofs, self.comm = fac, cdofs, fac.comm
        self.slot = {}                                   # global id -> column
        self.Zc = np.zeros((len(cdofs), 0))
        self.Zt = np.zeros((0, n_local))
        self.its = 0

    def _grow(self, need):
        """Room for ``need`` columns (capacity doubled, as in the schur strategy)."""
        n0, cap = len(self.slot), max(need, 2 * self.Zc.shape[1], 16)
        Zc = np.zeros((len(self.cdofs), cap))
        Zc[:, :n0] = self.Zc[:, :n0]
        self.Zc = Zc
        n_local = self.Zt.shape[1] if self.Zt is not None else 0
        if self.comm.allreduce(self.Zt is not None and cap * n_local * 8 <= SCHUR_COLUMN_MEMORY, op=MPI.LAND):
            Zt = np.zeros((cap, n_local))
            Zt[:n0] = self.Zt[:n0]
            self.Zt = Zt
        else:
            self.Zt = None

    def ensure(self, gids):
        """Solve and cache the columns of ``gids`` not cached yet (collective, same list)."""
        missing = [g for g in dict.fromkeys(gids.tolist()) if g not in self.slot]
        if not missing:
            return
        cols = self.fac.solve_columns(missing)
        self.its += len(missing)
        n0 = len(self.slot)
        if n0 + len(missing) > self.Zc.shape[1]:
            self._grow(n0 + len(missing))
        self.Zc[:, n0:n0 + len(missing)] = cols[self.cdofs, :]
        if self.Zt is not None:
            self.Zt[n0:n0 + len(missing)] = cols.T
        for k, g in enumerate(missing):
            self.slot[g] = n0 + k

    def has(self, gids):
        """Every one of ``gids`` is cached."""
        return all(g in self.slot for g in gids.tolist())

    def slots(self, gids):
        return np.fromiter((self.slot[g] for g in gids.tolist()), dtype=np.int64, count=len(gids))


class FrictionSystem:
    """The Newton systems of one step (see the module) on the contact dofs ``cdofs`` (owned
    local indices, the m normal dofs, then the m tangential ones).

    Args:
        K: the step matrix; fac: its :class:`~sdm_dolfinx.solvers.factorisation.Factorisation`.
        cdofs: this rank's contact dofs (normal, then tangential).
    """

    def __init__(self, K, cdofs, fac):
        self.K, self.fac, self.comm = K, fac, K.getComm().tompi4py()
        self.cdofs = np.asarray(cdofs, dtype=np.int32)
        self.gc = (K.getOwnershipRange()[0] + self.cdofs).astype(np.int64)
        self.cols = ColumnCache(fac, self.cdofs, K.getLocalSize()[0])
        self._x0, self._rhs = K.createVecRight(), K.createVecLeft()
        self.starts = 0
        #: (m, k, k) the nodes' frames (see the module), or None: the contact dofs themselves
        self.Q = None

    def set_frames(self, Q):
        """The frames of the next systems: Q[i] orthonormal (k x k, row 0 the normal) for node i, whose
        Cartesian dofs are ``cdofs[c * m + i]`` (c = 0..k-1); None: no rotation."""
        self.Q = None if Q is None else np.asarray(Q, dtype=float)

    def rotate(self, v):
        """The contact vector v (Cartesian, component-major) in the frames: (Q_i v_i)_k at k * m + i."""
        if self.Q is None:
            return v
        m, k = self.Q.shape[:2]
        return np.einsum("ikc,ci...->ki...", self.Q, v.reshape(k, m, *v.shape[1:])).reshape(v.shape)

    def unrotate(self, y):
        """The inverse of :meth:`rotate` (Q_i^T y_i)."""
        if self.Q is None:
            return y
        m, k = self.Q.shape[:2]
        return np.einsum("ikc,ki...->ci...", self.Q, y.reshape(k, m, *y.shape[1:])).reshape(y.shape)

    def impose(self, xa, active, lb, stick, xref):
        """Frames: in the owned array xa, the nodes' normal components Q_i[0] . x_i := lb on the active
        set and their tangential ones := xref (m, or m x 2) on the stick set (rotated, set, rotated back)."""
        m = len(active)
        if m == 0:
            return
        y = self.rotate(xa[self.cdofs].copy())
        y[:m][active] = lb[active]
        t = y[m:].reshape(-1, m)                    # a view: tangential component k - 1 of node i
        t[:, stick] = np.reshape(xref, (m, -1)).T[:, stick]
        xa[self.cdofs] = self.unrotate(y)

    def _columns(self, *masks):
        """For each mask of this rank's unknowns: (the global ids of the masked unknowns of every rank,
        this rank's offset among them, their columns K^-1 e_j at this rank's contact rows (a copy)).
        The columns not cached yet are solved in one batch (collective)."""
        parts = [self._gather(self.gc[mask]) for mask in masks]
        if self.Q is None:
            self.cols.ensure(np.concatenate([g for g, _ in parts]))
            return [(g, off, self.cols.Zc[:, self.cols.slots(g)]) for g, off in parts]
        m, k = self.Q.shape[:2]
        nodes = self.gc.reshape(k, m).T                  # (m, k) the Cartesian ids of each node
        combos = []
        for mask in masks:
            j = np.flatnonzero(mask)
            ids, _ = self._gather(nodes[j % m])
            coef, _ = self._gather(self.Q[j % m, j // m, :])
            combos.append((ids.reshape(-1, k), coef.reshape(-1, k)))
        self.cols.ensure(np.concatenate([ids.reshape(-1) for ids, _ in combos]))
        out = []
        for (g, off), (ids, coef) in zip(parts, combos):
            Z = np.zeros((len(self.cdofs), len(g)))
            for c in range(k):
                Z += self.cols.Zc[:, self.cols.slots(ids[:, c])] * coef[:, c]
            out.append((g, off, self.rotate(Z)))
        return out

    @property
    def its(self):
        """Solves with the factorisation: one per step (x0) and one per cached column."""
        return self.starts + self.cols.its

    def start(self, b):
        """x0 = K^-1 b, once per step; the iterations reuse it."""
        self.fac.solve(b, self._x0)
        self.starts += 1
        self._x0c = self.rotate(self._x0.array_r[self.cdofs].copy())

    def _gather(self, local):
        parts = self.comm.allgather(local)
        return np.concatenate(parts), sum(len(p) for p in parts[:self.comm.rank])

    def system(self, fixed, target, a, c, partner):
        """x at the contact dofs and their reactions r = (K x - b)_c for one Newton system.

        Args:
            fixed: bool, the dofs with a prescribed value ``target``.
            a, c: the forced reactions r_j = a_j + c_j r_partner(j) (zero: free dof);
                ``partner[j]`` (local contact index) is fixed wherever c_j != 0.

        Raises:
            VIError: the dense system is singular.
        """
        forced = ~fixed & ((a != 0.0) | (c != 0.0))
        (gF, offF, W), (gJ, _, ZJ) = self._columns(fixed, forced)
        pos = np.full(len(fixed), -1, dtype=np.int64)          # global position among the fixed
        pos[fixed] = offF + np.arange(np.count_nonzero(fixed))
        aJ, _ = self._gather(a[forced])
        cJ, _ = self._gather(c[forced])
        pJ, _ = self._gather(np.where(c[forced] != 0.0, pos[partner[forced]], -1))
        cpl = pJ >= 0                                # Coulomb: W = Z_F + Z_J D
        W[:, pJ[cpl]] += ZJ[:, cpl] * cJ[cpl]
        xc_known = self._x0c + ZJ @ aJ
        S = np.vstack(self.comm.allgather(W[fixed])) if len(gF) else np.zeros((0, 0))
        rhs, _ = self._gather(target[fixed] - xc_known[fixed])
        rF = solve_repeated(S, rhs, f"the frictional Newton system on {len(gF)} fixed contact dofs is singular "
                                    "(Coulomb with a large friction coefficient?)")
        xc = xc_known + W @ rF
        r = np.zeros(len(fixed))
        r[fixed] = rF[offF:offF + np.count_nonzero(fixed)]
        r[forced] = a[forced] + c[forced] * r[partner[forced]]
        self._last = r
        return xc, r

    def cone(self, active, stick, slip, lb, xref, A, B, e, q):
        """The 3-D Newton system (:mod:`~sdm_dolfinx.solvers.friction_cone`): x at the contact
        dofs (normal, then the two tangential components) and their reactions r.

        Conditions: x_n = lb (``active``), x_t = xref (``stick``, both components) and on the
        ``slip`` vertices the linearised cone, two rows per vertex i:
        A_i lam_T + B_i (x_t - xref) + e_i lam_N = q_i (A, B: m x 2 x 2; e, q: m x 2; e != 0
        only where the vertex is active); every other reaction 0. Unknowns: the reactions of
        those dofs, one dense (non-symmetric) system on the cached columns of K^-1.

        Raises:
            VIError: the dense system is singular.
        """
        m = len(active)
        on = np.concatenate([active, stick | slip, stick | slip])
        [(gS, off, Z)] = self._columns(on)                       # local contact rows x unknowns
        pos = np.full(3 * m, -1, dtype=np.int64)
        pos[on] = off + np.arange(np.count_nonzero(on))
        x0 = self._x0c
        ia, it, isl = np.flatnonzero(active), np.flatnonzero(stick), np.flatnonzero(slip)
        rows, rhs = [Z[ia], Z[m + it], Z[2 * m + it]], [lb[ia] - x0[ia], xref[it, 0] - x0[m + it],
                                                         xref[it, 1] - x0[2 * m + it]]
        n = np.arange(len(isl))
        for comp in (0, 1):                                      # the slip rows, component comp
            R = np.zeros((len(isl), len(gS)))
            rr = q[isl, comp].copy()
            for b in (0, 1):
                tb = m * (1 + b) + isl
                R[n, pos[tb]] += A[isl, comp, b]
                R += B[isl, comp, b][:, None] * Z[tb]
                rr -= B[isl, comp, b] * (x0[tb] - xref[isl, b])
            cpl = e[isl, comp] != 0.0
            R[n[cpl], pos[isl[cpl]]] += e[isl[cpl], comp]
            rows.append(R)
            rhs.append(rr)
        order = np.concatenate([pos[ia], pos[m + it], pos[2 * m + it], pos[m + isl], pos[2 * m + isl]])
        M = np.zeros((len(gS), len(gS)))
        y = np.zeros(len(gS))
        for part_rows, part_rhs, part_order in self.comm.allgather((np.vstack(rows), np.concatenate(rhs), order)):
            M[part_order] = part_rows
            y[part_order] = part_rhs
        rS = solve_repeated(M, y, f"the 3-D frictional Newton system on {len(gS)} contact dofs is singular "
                                  "(Coulomb with a large friction coefficient?)")
        r = np.zeros(3 * m)
        r[on] = rS[pos[on]]
        self._last = r
        return x0 + Z @ rS, r

    def finish(self, b, x):
        """The full x of the last :meth:`system`: x0 + sum_j r_j K^-1 e_j over the (at most
        :data:`FINISH_MAX_AXPY`) cached columns with a reaction, one contiguous axpy each,
        else one more solve K x = b + E r (frames: the reactions Q_i^T r_i of the Cartesian dofs)."""
        last = self.unrotate(self._last)
        nz = np.flatnonzero(last)
        gids, _ = self._gather(self.gc[nz])
        if self.cols.Zt is None or len(gids) > FINISH_MAX_AXPY or not self.cols.has(gids):
            b.copy(self._rhs)
            self._rhs.array[self.cdofs] += last
            self.fac.solve(self._rhs, x)
            self.starts += 1
            return
        xa = x.array
        xa[:] = self._x0.array_r
        for j, rj in zip(self.cols.slots(gids), self._gather(last[nz])[0]):
            xa += rj * self.cols.Zt[j]

    def destroy(self):
        self._x0.destroy()
        self._rhs.destroy()
