"""The penalty step solver: K x = b + P^T lam(x_c),  lam_i = k_i (lb_i - x_{c_i})_+.

With the contact replaced by a penalty (:mod:`sdm_dolfinx.contact.penalty`), each step
of every scheme is this nonlinear system: K the constant step matrix (Dirichlet rows are
identity rows), c the constrained dofs, lb their bounds, k > 0 the penalty stiffnesses. With
x0 = K^-1 b and Z = K^-1 P^T, x = x0 + Z lam: only x_c matters, x_c = x0_c + S lam with
S = P K^-1 P^T, the Schur complement of K on the constrained dofs (SPD for SPD K). The
semi-smooth Newton method on G(x_c) = x_c - x0_c - S lam(x_c) with active set
A = {x_c < lb} solves, at each iteration, for mu = lam_A:

    (S_AA + diag(1/k_A)) mu = lb_A - x0_A,    x_c = x0_c + S_{:,A} mu,    x_A = lb_A - mu / k_A,

the exact contact's Schur system (:class:`~sdm_dolfinx.solvers.schur.SchurComplement`) plus the
penalty's compliance 1/k_A on its diagonal. The solver is the default step solver
(:class:`~sdm_dolfinx.solvers.semismooth.SemismoothNewton`, its SNES, options, monitors and
Murty safeguard) with that system: K is factorised once per run, a column K^-1 e_i is computed
once per constraint ever active (cached), one solve per step. Its active-set test is the
same: release an active dof whose mu < 0 (x_i > lb_i), add an inactive one below its bound, so
at convergence lam = k (lb - x_c)_+ holds with the final active set (to round-off). An active
set beyond the Schur strategy's size falls back to CG (GMRES) on K + P^T diag(k_A) P
preconditioned by the same factorisation, which differs from K^-1 by a term of rank |A|
(at most |A| + 1 iterations).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.solvers.base import VIError
from sdm_dolfinx.solvers.options import ksp_reason_name
from sdm_dolfinx.solvers.schur import SchurComplement
from sdm_dolfinx.solvers.semismooth import SemismoothNewton


class PenaltySchur(SchurComplement):
    """:class:`SchurComplement` whose Newton systems carry the compliance 1/k on their diagonal.

    :meth:`system` lets the parent gather the active set, check its size against the Schur
    strategy's limits and cache the missing columns (its own dense solve is discarded: |A|^3
    flops, |A| <= 100), then solves (S_AA + diag(1/k_A)) mu = lb_A - x0_A.
    """

    def __init__(self, K, cdofs, lb, fac, k):
        super().__init__(K, cdofs, lb, fac)
        self.k = np.asarray(k, dtype=float)
        self._xc = None

    def system(self, active):
        """x_c and lam (mu on the active set, 0 elsewhere) of the penalised Newton system
        with active set ``active``, or None when the set is too large (Krylov instead)."""
        if super().system(active) is None:
            return None
        comm, rows, slots = self.comm, np.flatnonzero(active), self._slots
        parts = comm.allgather(len(rows))
        S = np.vstack(comm.allgather(self._Zc[np.ix_(rows, slots)])) if len(slots) else np.zeros((0, 0))
        r = np.concatenate(comm.allgather(self.lb[active] - self._x0c[active]))
        S[np.diag_indices_from(S)] += np.concatenate(comm.allgather(1.0 / self.k[active]))
        mu = np.linalg.solve(S, r) if len(slots) else np.zeros(0)
        off = sum(parts[:comm.rank])
        self._mu, self._mu_local = mu, mu[off:off + len(rows)]
        xc = self._x0c + self._Zc[:, slots] @ mu
        lam = np.zeros(len(self.cdofs))
        lam[rows] = self._mu_local
        self._xc = xc
        return xc, lam

    def finish(self, b, x, active):
        """The full x of the accepted active set: the parent's x0 + Z_A mu (or one more solve
        with b + E_A mu), with x_A = lb_A - mu / k_A instead of lb_A."""
        super().finish(b, x, active)
        x.array[self.cdofs[active]] = self._xc[active]


class _PenalisedOperator:
    """y = (K + P^T diag(k_A) P) x: K plus the active penalty springs."""

    def __init__(self, K, cdofs):
        self.K, self.cdofs = K, cdofs
        self.kA = np.zeros(len(cdofs))

    def mult(self, mat, x, y):
        self.K.mult(x, y)
        y.array[self.cdofs] += self.kA * x.getArray(readonly=True)[self.cdofs]


class _FactorPC:
    """z = K^-1 r by the run's factorisation (a rank-|A| perturbation of the operator's inverse)."""

    def __init__(self, fac):
        self.fac = fac

    def apply(self, pc, r, z):
        self.fac.solve(r, z)


class PenaltyKrylov:
    """Newton systems of large active sets: (K + P^T diag(k_A) P) x = b + P^T (k_A lb_A) by CG
    (GMRES for a symmetric indefinite K) preconditioned by the factorisation of K.

    Same interface as :class:`~sdm_dolfinx.solvers.active_set.InactiveSetSolver`:
    ``solve(b, x, active, work)`` returns (x_c, lam) with lam = k (lb - x_c) on the active set.
    """

    def __init__(self, K, cdofs, lb, k, spd, prefix, fac):
        self.cdofs, self.lb, self.k = cdofs, lb, np.asarray(k, dtype=float)
        self.comm = K.getComm().tompi4py()
        self.its = 0
        n, N = K.getLocalSize()[0], K.getSize()[0]
        self.ctx = _PenalisedOperator(K, cdofs)
        self.op = PETSc.Mat().createPython([(n, N), (n, N)], self.ctx, comm=self.comm)
        self.op.setUp()
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOptionsPrefix(prefix + "penalty_")
        ksp.setOperators(self.op)
        ksp.setType("cg" if spd else "gmres")
        ksp.setTolerances(rtol=1e-12, atol=1e-50, max_it=5000)
        pc = ksp.getPC()
        pc.setType("python")
        pc.setPythonContext(_FactorPC(fac))
        ksp.setFromOptions()
        self.ksp = ksp

    def solve(self, b, x, active, work):
        c, lb, k = self.cdofs, self.lb, self.k
        rhs = work[0]
        self.ctx.kA = np.where(active, k, 0.0)
        b.copy(rhs)
        rhs.array[c] += self.ctx.kA * lb
        self.op.assemble()
        self.ksp.solve(rhs, x)
        reason = self.ksp.getConvergedReason()
        self.its += max(self.ksp.getIterationNumber(), 1)
        if reason <= 0:
            raise VIError(f"penalty: linear solve with {int(np.count_nonzero(active))} active springs failed "
                          f"(KSP reason {reason}: {ksp_reason_name(reason)})")
        xc = x.array_r[c].copy()
        return xc, np.where(active, k * (lb - xc), 0.0)

    def destroy(self):
        self.ksp.destroy()
        self.op.destroy()


class PenaltyNewton(SemismoothNewton):
    """The step solver of the penalised contact: K x = b + P^T k (lb - x_c)_+ (see the module).

    Args:
        K: the step matrix (PETSc Mat, Dirichlet rows = identity rows).
        cdofs: owned local indices of the constrained entries of x.
        lb: their bounds.
        k: their penalty stiffnesses (> 0, force per unit of penetration).
        symmetric_positive: K is SPD (Cholesky, CG) or only symmetric (LDL^T / LU, GMRES).
        prefix, options, factor_matrix, rtol, max_it: as for
            :class:`~sdm_dolfinx.solvers.semismooth.SemismoothNewton` (the linear strategy is
            ``schur``: one factorisation of K, or of ``factor_matrix``, per run).

    ``lam`` (the owned constrained dofs' penalty forces, >= 0), ``active`` (penetrating dofs),
    ``total_linear_its`` and ``solve(b, x) -> {"its", "n_active"}`` as every step solver.
    """

    def __init__(self, K, cdofs, lb, k, symmetric_positive=True, prefix=None, options=None, factor_matrix=None,
                 rtol=1e-10, max_it=500):
        self.k = np.asarray(k, dtype=float)
        if self.k.shape != np.shape(cdofs):
            raise ValueError(f"penalty: {self.k.size} stiffnesses for {np.size(cdofs)} constrained dofs")
        comm = K.getComm().tompi4py()
        if not comm.allreduce(bool(np.all(np.isfinite(self.k) & (self.k > 0.0))), op=MPI.LAND):
            raise ValueError("penalty: every stiffness k_i must be finite and > 0")
        super().__init__(K, cdofs, lb, symmetric_positive, "schur", prefix=prefix, options=options,
                         factor_matrix=factor_matrix, rtol=rtol, max_it=max_it)

    def _setup(self, K):
        """The semi-smooth Newton's set-up with the penalised Schur system and Krylov fallback."""
        super()._setup(K)
        self.schur.destroy()
        self.inactive.destroy()
        self.schur = PenaltySchur(K, self.cdofs, self.lb, self.fac, self.k)
        self.inactive = PenaltyKrylov(K, self.cdofs, self.lb, self.k, self.spd, self.prefix, self.fac)

    def residual(self, x):
        """lam - k (lb - x_c)_+ at the owned constrained dofs (0 at a solution)."""
        return self.lam - self.k * np.maximum(self.lb - x.array_r[self.cdofs], 0.0)
