"""The ``schur`` linear strategy: Newton systems on the active set by a small dense Schur
complement built from cached columns of K^-1.

K is factorised once per run (:class:`~sdm_dolfinx.solvers.factorisation.Factorisation`).
With x0 = K^-1 b (one solve per step) and Z = K^-1 E_A the columns of the active
constraints (each computed once per run and cached), a Newton system x_A = lb_A,
(K x - b)_I = 0 is x = x0 + Z mu with mu from the dense |A| x |A| system
(E_A^T Z) mu = lb_A - x0_A; mu is the multiplier. The Newton iterations are then dense
work only; large active sets fall back to Krylov (:mod:`sdm_dolfinx.solvers.active_set`).
"""
import time

from mpi4py import MPI

import numpy as np

#: ``schur`` solves a Newton system by the dense Schur complement while |active| is at most a
#: threshold between SCHUR_MAX_ACTIVE and SCHUR_MAX_COLUMNS (and at most SCHUR_MAX_COLUMNS
#: columns are cached); otherwise by CG (GMRES) on the inactive set preconditioned by the same
#: factorisation (``cg-factor``). The threshold is measured once per run (SCHUR_COST_MODEL,
#: :meth:`SchurComplement.max_active`): m with SCHUR_DENSE_FACTOR c3 m^3 = SCHUR_FALLBACK_SOLVES
#: t_solve, c3 m^3 the time of a dense solve of size m (c3 timed on the machine at m = 256),
#: t_solve that of one solve with the factorisation (the fastest step solve so far). Measured on
#: 1 rank at load ~4: membrane N = 80 (t_solve 0.25 ms) impact steps take 63 ms with the threshold
#: 100, 172 ms with 294, 162 ms with 1000 (the dense path's new columns, gathers and products cost
#: ~30 times c3 m^3 at m ~ 300: SCHUR_DENSE_FACTOR; the model then gives 100); ball level 3
#: (t_solve 0.14 s), 50 steps from the contact's start, up to 168 active: the model gives 784,
#: 0.95 s per step (4.4 solves) against 8.7 s (27 solves) with 100, load 2-3.5.
SCHUR_MAX_ACTIVE = 100
SCHUR_MAX_COLUMNS = 1000
#: False: the threshold is SCHUR_MAX_ACTIVE itself (tests that force the CG fallback)
SCHUR_COST_MODEL = False
#: ... off by default: a threshold timed at run time made a restarted run (which times it again)
#: and two runs of the same input take different paths (dense or CG) and differ at round-off
#: (tests/integration/test_restart.py); the step solver takes a fixed threshold instead:
#: SCHUR_MAX_ACTIVE, or the option -<prefix>schur_max_active, which the integrator sets to
#: SCHUR_MAX_ACTIVE_3D on tetrahedra (the cost model's measured 784 at ball level 3)
SCHUR_MAX_ACTIVE_3D = 1000
#: solves per Newton iteration of the CG fallback (measured: membrane N = 80 ~14, ball level 3 ~24)
SCHUR_FALLBACK_SOLVES = 14
#: the dense path's cost per Newton iteration over c3 m^3 (measured, membrane N = 80; see above)
SCHUR_DENSE_FACTOR = 30

#: full cached columns K^-1 e_i are kept while they take less than this per rank (bytes);
#: beyond, each step ends with one more solve instead of a product with the columns
SCHUR_COLUMN_MEMORY = 2 * 1024 ** 3


class SchurComplement:
    """The Newton systems of one step by the cached columns K^-1 e_i (see the module).

    Args:
        K: the step matrix.
        cdofs: owned local indices of the constrained entries of x.
        lb: their lower bounds.
        fac: the factorisation of K.

    ``its`` counts the solves with the factorisation (one per column, one per step).
    """

    def __init__(self, K, cdofs, lb, fac, max_active=None):
        self.K, self.cdofs, self.lb, self.fac = K, cdofs, lb, fac
        self._fixed_max_active = max_active
        self.comm = K.getComm().tompi4py()
        self.its = 0
        self.gc = (self.K.getOwnershipRange()[0] + self.cdofs).astype(np.int64)   # global ids
        self._slot = {}                                   # global id -> column slot
        self._Zc = np.zeros((len(self.cdofs), 0))         # cached columns at the constraints
        # ... and in full (if they fit), column-major: finish() adds whole columns, and a row-major
        # array's scattered columns cost 72 ms to gather at 126k rows x 40 (the disc, level 5)
        self._Zf = np.zeros((self.K.getLocalSize()[0], 0), order="F")
        self._full = True
        self._ncols = 0
        self._x0 = self.K.createVecRight()
        self._rhs = self.K.createVecLeft()
        self._t_solve = np.inf          # the fastest step solve so far (s)
        self._max_active = None         # measured once (max_active)

    def start(self, b):
        """x0 = K^-1 b, once per step; the iterations reuse it."""
        t0 = time.perf_counter()
        self.fac.solve(b, self._x0)
        self._t_solve = min(self._t_solve, time.perf_counter() - t0)
        self.its += 1
        self._x0c = self._x0.array_r[self.cdofs].copy()

    def _ensure_columns(self, gids):
        """Compute and cache K^-1 e_g for the ids not cached yet (collective, same list)."""
        missing = [g for g in gids if g not in self._slot]
        if not missing:
            return
        cols = self.fac.solve_columns(missing)
        self.its += len(missing)
        k = len(missing)
        need = self._ncols + k
        if need > self._Zc.shape[1]:
            cap = max(need, 2 * self._Zc.shape[1], 16)
            Zc = np.zeros((self._Zc.shape[0], cap))
            Zc[:, :self._ncols] = self._Zc[:, :self._ncols]
            self._Zc = Zc
            full_ok = self.comm.allreduce(self._Zf.shape[0] * cap * 8 <= SCHUR_COLUMN_MEMORY, op=MPI.LAND)
            if self._full and full_ok:
                Zf = np.zeros((self._Zf.shape[0], cap), order="F")
                Zf[:, :self._ncols] = self._Zf[:, :self._ncols]
                self._Zf = Zf
            else:
                self._full, self._Zf = False, None
        self._Zc[:, self._ncols:need] = cols[self.cdofs, :]
        if self._full:
            self._Zf[:, self._ncols:need] = cols
        for j, g in enumerate(missing):
            self._slot[g] = self._ncols + j
        self._ncols = need

    def max_active(self):
        """The largest active set solved by the dense system (collective; measured once, at the
        first active set above SCHUR_MAX_ACTIVE), within [SCHUR_MAX_ACTIVE, SCHUR_MAX_COLUMNS]
        (the cost model: see the module's constants)."""
        if self._fixed_max_active is not None:
            return self._fixed_max_active
        if not SCHUR_COST_MODEL:
            return SCHUR_MAX_ACTIVE
        if self._max_active is None:
            m, rng = 256, np.random.default_rng(0)
            S = rng.random((m, m)) + m * np.eye(m)
            r = np.ones(m)
            t = np.inf
            for _ in range(3):
                t0 = time.perf_counter()
                np.linalg.solve(S, r)
                t = min(t, time.perf_counter() - t0)
            m_star = (SCHUR_FALLBACK_SOLVES * self._t_solve * m ** 3 / (SCHUR_DENSE_FACTOR * t)) ** (1.0 / 3.0)
            m_star = int(min(max(m_star, SCHUR_MAX_ACTIVE), SCHUR_MAX_COLUMNS))
            self._max_active = self.comm.allreduce(m_star, op=MPI.MIN)
        return self._max_active

    def system(self, active):
        """x_c and the multipliers for active set ``active`` from the cached columns, or None
        when the active set is too large (then Krylov on the inactive set instead).

        With x = x0 + Z mu (x0 = K^-1 b, Z = K^-1 E_A), K x - b = E_A mu: mu is the
        multiplier, and x_A = lb_A is the dense SPD system (Z_AA) mu = lb_A - x0_A (Z_AA is
        the constrained block of K^-1; of its Schur complement for the block formulation).
        """
        comm = self.comm
        la = self.gc[active]
        parts = comm.allgather(la)
        gA = np.concatenate(parts) if parts else la
        new = sum(1 for g in gA.tolist() if g not in self._slot)
        if self._ncols + new > SCHUR_MAX_COLUMNS or (len(gA) > SCHUR_MAX_ACTIVE and len(gA) > self.max_active()):
            return None                                    # too large: Krylov instead
        self._ensure_columns(gA.tolist())
        slots = np.array([self._slot[g] for g in gA.tolist()], dtype=np.int64)
        rows = np.flatnonzero(active)
        S_loc = self._Zc[np.ix_(rows, slots)]
        r_loc = self.lb[active] - self._x0c[active]
        S = np.vstack(comm.allgather(S_loc)) if len(gA) else np.zeros((0, 0))
        r = np.concatenate(comm.allgather(r_loc))
        mu = np.linalg.solve(S, r) if len(gA) else np.zeros(0)
        xc = self._x0c + self._Zc[:, slots] @ mu
        off = sum(len(p) for p in parts[:comm.rank])
        lam = np.zeros(len(self.cdofs))
        lam[rows] = mu[off:off + len(rows)]
        self._mu, self._slots, self._mu_local = mu, slots, mu[off:off + len(rows)]
        return xc, lam

    def finish(self, b, x, active):
        """The full x of the accepted active set (the last :meth:`system`)."""
        c = self.cdofs
        if self._full:          # x0 + Z_A mu, one contiguous column at a time (no copy of Z_A)
            out = self._x0.array_r.copy()
            for slot, m in zip(self._slots, self._mu):
                out += m * self._Zf[:, slot]
            x.array[:] = out
        else:           # one more solve: K x = b + E_A mu
            b.copy(self._rhs)
            self._rhs.array[c[active]] += self._mu_local
            self.fac.solve(self._rhs, x)
            self.its += 1
        x.array[c[active]] = self.lb[active]

    def destroy(self):
        self._x0.destroy()
        self._rhs.destroy()
