"""The step solver of Nitsche's contact: Newton's method on F(X) = K X - b + R_N(X) = 0.

R_N is the Nitsche boundary residual (:mod:`.nitsche`): piecewise linear in X (its [.]_- switches
at each quadrature point of the contact boundary), so its Jacobian J_N is piecewise constant and
changes only with the set of quadrature points in contact. R_N reads X only at, and writes only
to, the dofs B of the cells along the contact boundary. Two ways to solve:

* ``reduced`` (|B| <= SCHUR_MAX_COLUMNS, the usual case): K is factorised once per run and the
  columns Z = K^-1 E_B computed once (the penalty and exact solvers' Schur complement cache,
  :class:`~sdm_dolfinx.solvers.schur.SchurComplement`); with x0 = K^-1 b (one solve per step),
  X = x0 + Z lam_B, and Newton runs on the |B| unknowns y = X_B:
  y - x0_B - Z_BB lam_B(y) = 0, Jacobian I + Z_BB J_N[B, B] (dense, its LU kept for the last few
  J_N met, as below). X is then x0 + Z lam_B (the cached full columns) or one more solve.
* ``full`` (larger B): the Newton matrix K + J_N is factorised (MUMPS LU: J_N is not symmetric
  for theta != 1) for each J_N met and kept (the last few, :data:`CACHED_FACTORISATIONS`).

Termination is exact for a piecewise linear F: after a Newton step computed with J_N, if J_N at
the new iterate is the same, the iterate solves F = 0 to round-off; it is accepted when moreover
its residual is below 1e-8 (a safety net), or at once when below ``rtol`` (a quadrature point
switching at P = 0 changes J_N but not F); residuals relative to max|b| (full) or to max|y|
(reduced).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import scipy.linalg
import scipy.sparse

from sdm_dolfinx.solvers import Factorisation, VIError
from sdm_dolfinx.solvers.factorisation import factorise
from sdm_dolfinx.solvers.options import instance_prefix
from sdm_dolfinx.solvers.schur import SCHUR_MAX_COLUMNS, SchurComplement

#: residual (relative) below which an iterate whose Jacobian did not change is accepted
SAME_SET_RTOL = 1e-8
#: factorisations kept by the full strategy (by their J_N): the initial guess U^n and the
#: solution X of a midpoint step in contact often lie in different contact sets (a massless
#: contact node's U^n alternates about the bound)
CACHED_FACTORISATIONS = 4


class NitscheNewton:
    """Newton's method for K X = b + lam(X), lam = -R_N (see the module).

    Args:
        K: the step matrix of the M formulation (Dirichlet rows identity rows, SPD; the
            Integrator refuses a contact treatment with the (U, V) block system).
        nitsche: the :class:`~sdm_dolfinx.contact.nitsche.Nitsche` treatment: its
            ``set_state(x)``, ``residual()`` (W^h vector, Dirichlet rows 0), ``jacobian()``
            (W^h matrix, Dirichlet rows and columns 0), ``pressure_forces()``, ``dofs`` (B:
            global indices, owned local ones).
        factor_matrix: a sparser matrix to factorise instead of K (the Integrator's).
        rtol: the residual that accepts any iterate; max_it: Newton iterations per step.
    """

    def __init__(self, K, nitsche, factor_matrix=None, prefix=None, rtol=1e-12, max_it=50):
        self.K, self.nitsche = K, nitsche
        self.comm = K.getComm().tompi4py()
        self.prefix = instance_prefix(self.comm, prefix)
        self.rtol, self.max_it = rtol, max_it
        self.F, self.dx = K.createVecLeft(), K.createVecRight()
        self.gB, self.own = nitsche.dofs
        self.strategy = "reduced" if len(self.gB) <= SCHUR_MAX_COLUMNS else "full"
        self.factor_matrix, self.fac, self.schur = factor_matrix, None, None
        # (J_N, K + J_N, its factorisation) [full] or (J_N, LU of I - Z_BB G) [reduced], most recent first
        self.cache = []
        ncon = len(nitsche.discretisation.cdofs)
        self.lam, self.active = np.zeros(ncon), np.zeros(ncon, dtype=bool)
        self.factorisations = 0

    @property
    def total_linear_its(self):
        """Solves with a factorisation so far (the columns of Z included)."""
        return self.schur.its if self.schur is not None else self._full_solves

    _full_solves = 0

    def solve(self, b, x):
        """Solve K x = b + lam(x); x holds the initial guess and the result.

        Returns:
            dict with ``its`` (Newton iterations) and ``n_active`` (constrained vertices with a
            positive contact pressure).

        Raises:
            VIError: no convergence in ``max_it`` iterations.
        """
        its = self._reduced(b, x) if self.strategy == "reduced" else self._full(b, x)
        self.nitsche.set_state(x)
        self.lam = self.nitsche.pressure_forces()
        self.active = self.lam > 0.0
        n_active = self.comm.allreduce(int(np.count_nonzero(self.active)), op=MPI.SUM)
        return {"its": its, "n_active": n_active}

    # ------------------------------------------------------------------ reduced
    def _gather(self, local):
        return np.concatenate(self.comm.allgather(np.asarray(local)))

    def _columns(self):
        """The factorisation, the columns Z = K^-1 E_B and Z_BB (once per run)."""
        self.fac = Factorisation(self.K, True, self.prefix + "factor_", aug=self.factor_matrix)
        self.factorisations += 1
        self.schur = SchurComplement(self.K, self.own, np.zeros(len(self.own)), self.fac)
        self.schur._ensure_columns(self.gB.tolist())
        slots = np.array([self.schur._slot[g] for g in self.gB.tolist()], dtype=np.int64)
        # the columns were computed in B's order: a slice of the cache, not a copy of it
        self.slots = slice(0, len(slots)) if np.array_equal(slots, np.arange(len(slots))) else slots
        self.Z_BB = np.vstack(self.comm.allgather(self.schur._Zc[:, self.slots]))

    def _lam_and_jacobian(self, x, y):
        """lam_B(y) and d lam_B / d y = -J_N[B, B] at X = x0 except X_B = y (x holds x0)."""
        x.array[self.own] = y[self._off:self._off + len(self.own)]
        self.nitsche.set_state(x)
        lam = -self._gather(self.nitsche.residual().array_r[self.own])
        rows = (self.K.getOwnershipRange()[0] + self.own).astype(PETSc.IntType)
        JN = self.nitsche.jacobian()
        block = JN.getValues(rows, self.gB.astype(PETSc.IntType)) if len(rows) else np.zeros((0, len(self.gB)))
        return lam, -np.vstack(self.comm.allgather(np.reshape(block, (len(rows), len(self.gB))))), JN

    def _reduced(self, b, x):
        """Newton on y = X_B (see the module); x: the guess's X_B is the first y; the result."""
        if self.schur is None:
            self._columns()
        self._off = sum(self.comm.allgather(len(self.own))[:self.comm.rank])
        s = self.schur
        y = self._gather(x.array_r[self.own])
        s.start(b)
        x0B = self._gather(s._x0c)
        x.array[:] = s._x0.array_r
        lam, G, JN = self._lam_and_jacobian(x, y)
        its, last = 0, None
        while True:
            res = y - x0B - self.Z_BB @ lam
            scale = max(np.max(np.abs(y), initial=0.0), np.max(np.abs(x0B), initial=0.0), 1e-300)
            rnorm = np.max(np.abs(res), initial=0.0) / scale
            if rnorm <= self.rtol or (last is not None and rnorm <= SAME_SET_RTOL and JN.equal(last)):
                break
            if its == self.max_it:
                raise VIError(f"Nitsche contact: Newton did not converge in {self.max_it} iterations "
                              f"(residual {rnorm:.3e} relative to max|X_B|)")
            y = y - scipy.linalg.lu_solve(self._newton_matrix(JN, G), res)
            its += 1
            if last is not None:
                last.destroy()
            last = JN.copy()
            lam, G, JN = self._lam_and_jacobian(x, y)
        if last is not None:
            last.destroy()
        self._finish(b, x, lam)
        return its

    def _newton_matrix(self, JN, G):
        """The LU factors of I - Z_BB G: cached ones whose J_N equals this one, else new ones."""
        for i, entry in enumerate(self.cache):
            if JN.equal(entry[0]):
                self.cache.insert(0, self.cache.pop(i))
                return entry[1]
        ZG = (scipy.sparse.csr_matrix(G).T @ self.Z_BB.T).T        # G is sparse: the cells' couplings
        lu = scipy.linalg.lu_factor(np.eye(len(G)) - ZG, overwrite_a=True)
        self.cache.insert(0, (JN.copy(), lu))
        while len(self.cache) > CACHED_FACTORISATIONS:
            self.cache.pop()[0].destroy()
        return lu

    def _finish(self, b, x, lam):
        """X = x0 + Z lam_B (cached full columns) or the solve K X = b + E_B lam_B."""
        s = self.schur
        if s._full:
            x.array[:] = s._x0.array_r + s._Zf[:, self.slots] @ lam
            return
        b.copy(s._rhs)
        s._rhs.array[self.own] += lam[self._off:self._off + len(self.own)]
        self.fac.solve(s._rhs, x)
        s.its += 1

    # ------------------------------------------------------------------ full
    def _residual(self, b, x):
        """F = K x - b + R_N(x) into self.F; returns |F|_inf."""
        self.nitsche.set_state(x)
        R = self.nitsche.residual()
        self.K.mult(x, self.F)
        self.F.axpy(-1.0, b)
        self.F.array[:] += R.array_r
        return self.F.norm(PETSc.NormType.NORM_INFINITY)

    def _factorise(self, JN):
        """The factorisation of K + J_N: a cached one whose J_N equals this one (moved to the
        front), else a new one (the oldest dropped beyond :data:`CACHED_FACTORISATIONS`)."""
        for i, entry in enumerate(self.cache):
            if JN.equal(entry[0]):
                self.cache.insert(0, self.cache.pop(i))
                return entry[2]
        J = self.K.copy()
        J.axpy(1.0, JN, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        ksp = factorise(J, self.comm, self.prefix + "factor_", kind="lu", package="mumps")
        self.factorisations += 1
        self.cache.insert(0, (JN.copy(), J, ksp))
        while len(self.cache) > CACHED_FACTORISATIONS:
            for o in self.cache.pop():
                o.destroy()
        return ksp

    def _full(self, b, x):
        """Newton with K + J_N (see the module); returns the iterations."""
        scale = max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        fnorm = self._residual(b, x)
        its = 0
        JN = self.nitsche.jacobian()
        while fnorm > self.rtol * scale:
            if its == self.max_it:
                raise VIError(f"Nitsche contact: Newton did not converge in {self.max_it} iterations "
                              f"(|F| = {fnorm:.3e}, max|b| = {scale:.3e})")
            self._factorise(JN).solve(self.F, self.dx)
            self._full_solves += 1
            its += 1
            x.axpy(-1.0, self.dx)
            fnorm = self._residual(b, x)
            JN = self.nitsche.jacobian()
            if fnorm <= SAME_SET_RTOL * scale and JN.equal(self.cache[0][0]):
                break
        return its

    def destroy(self):
        for entry in self.cache:
            for o in entry:
                if hasattr(o, "destroy"):
                    o.destroy()
        self.cache = []
        for o in (self.schur, self.fac, self.F, self.dx):
            if o is not None:
                o.destroy()
