"""Solves with the mass matrix for the schemes that need M^-1 or M's range (method/schemes).

* :class:`MassSolver`: a = M^-1 F for the explicit schemes. A diagonal M (the row-sum lumped
  mass) is divided by; any other is factorised once (Cholesky: CHOLMOD on one rank, MUMPS or
  a redundant copy on several, :class:`~sdm_dolfinx.solvers.factorisation.Factorisation`).
  Dofs without mass (the zero rows of a redistributed mass) and Dirichlet dofs get a = 0 (M
  with identity rows there, as GetFEM's demo's ``M2``).
* :func:`least_squares_acceleration`: a with M a = the part of F in the range of M, for a
  singular M too (Newmark's initial acceleration): LSQR.
* :func:`largest_eigenvalue`: omega_max^2, the largest eigenvalue of M^-1 K (the CFL bound of
  an explicit scheme), by SLEPc's Krylov-Schur on a shell operator, or power iterations when
  slepc4py is missing.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.method import step_matrix as _step_matrix
from sdm_dolfinx.solvers import Factorisation, VIError
from sdm_dolfinx.solvers.options import instance_prefix

#: a row of M whose absolute sum is at most this times M's largest diagonal entry has no mass
MASSLESS_RTOL = 1e-14


def _local_csr(M):
    """(row of each local entry (global index), column, value) of M's owned rows."""
    indptr, cols, vals = M.getValuesCSR()
    r0 = M.getOwnershipRange()[0]
    rows = r0 + np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
    return rows, cols, vals


def is_diagonal(M):
    """True when M has no nonzero entry off its diagonal (collective)."""
    rows, cols, vals = _local_csr(M)
    off = float(np.max(np.abs(vals[rows != cols]), initial=0.0))
    return M.getComm().tompi4py().allreduce(off, op=MPI.MAX) == 0.0


def massless_dofs(M):
    """Local indices of M's owned rows without mass (absolute row sum <= MASSLESS_RTOL x the
    largest diagonal entry), e.g. the contact dofs of a redistributed mass."""
    comm = M.getComm().tompi4py()
    rows, _, vals = _local_csr(M)
    r0, n = M.getOwnershipRange()[0], M.getLocalSize()[0]
    absum = np.bincount(rows - r0, weights=np.abs(vals), minlength=n)
    scale = comm.allreduce(float(np.max(M.getDiagonal().array, initial=0.0)), op=MPI.MAX)
    return np.flatnonzero(absum <= MASSLESS_RTOL * scale).astype(np.int32)


class MassSolver:
    """a = M^-1 F with a = 0 at the Dirichlet dofs and at the dofs without mass.

    Args:
        d: the Discretisation (its M formed).
        massless: local indices of the dofs without mass (see :func:`massless_dofs`).
    """

    def __init__(self, d, massless=()):
        self.zero = np.union1d(np.asarray(massless, dtype=np.int32), d.ddofs).astype(np.int32)
        self.massless = np.asarray(massless, dtype=np.int32)
        self.M2 = _step_matrix.identity_rows(d.M.copy(), self.zero)
        self.diagonal = is_diagonal(self.M2)
        self.fac, self.inv = None, None
        if self.diagonal:
            self.inv = 1.0 / self.M2.getDiagonal().array
        else:
            self.fac = Factorisation(self.M2, True, instance_prefix(d.comm) + "mass_")
        self._F = self.M2.createVecLeft()
        self.solves = 0

    def solve(self, F, out):
        """out = M^-1 F, zero at the Dirichlet and massless dofs (F itself is not changed)."""
        self.solves += 1
        if self.diagonal:
            out.array[:] = F.array_r * self.inv
            out.array[self.zero] = 0.0
            return out
        self._F.array[:] = F.array_r
        self._F.array[self.zero] = 0.0
        self.fac.solve(self._F, out)
        return out

    def destroy(self):
        self.M2.destroy()
        self._F.destroy()
        if self.fac is not None:
            self.fac.destroy()


def least_squares_acceleration(d, F, rtol=1e-14):
    """a with M a = the projection of F onto the range of M (M a = F for an invertible M), a = 0
    and F ignored at the Dirichlet dofs: LSQR on M with identity Dirichlet rows, from a = 0.

    For a singular M (the singular dynamic method, a redistributed mass) F's part in ker M
    (the massless dofs' unbalanced force) has no acceleration; dropping it is GetFEM's choice
    (its demo zeroes the contact node's initial M a) for any kernel.
    """
    M = _step_matrix.identity_rows(d.M.copy(), d.ddofs)
    rhs = F.copy()
    rhs.array[d.ddofs] = 0.0
    a = M.createVecRight()
    ksp = PETSc.KSP().create(d.comm)
    ksp.setOperators(M)
    ksp.setType("lsqr")
    ksp.getPC().setType("none")
    ksp.setTolerances(rtol=rtol, atol=0.0, max_it=100_000)
    ksp.solve(rhs, a)
    reason = ksp.getConvergedReason()
    for obj in (ksp, M, rhs):
        obj.destroy()
    if reason <= 0:
        raise VIError(f"the initial acceleration M a = L - A U0 was not found (LSQR reason {reason})")
    a.array[d.ddofs] = 0.0
    return a


class _Operator:
    """y = M^-1 (K x) (shell matrix context): ``stiffness(x, y)`` is y = K x."""

    def __init__(self, stiffness, mass_solver, template):
        self.stiffness, self.mass = stiffness, mass_solver
        self.t = template.duplicate()

    def mult(self, mat, x, y):
        self.stiffness(x, self.t)
        self.mass.solve(self.t, y)


def largest_eigenvalue(stiffness, mass_solver, template, rtol=1e-10):
    """The largest eigenvalue of M^-1 K (real, >= 0: K symmetric positive semi-definite, M SPD
    where it acts), collective. ``stiffness(x, y)``: y = K x; ``template``: a vector of W^h.

    SLEPc Krylov-Schur (largest real part, relative tolerance ``rtol``), or without slepc4py
    300 power iterations (a lower bound that the Rayleigh quotient approaches from below).
    """
    comm = template.getComm()
    n, N = template.getLocalSize(), template.getSize()
    ctx = _Operator(stiffness, mass_solver, template)
    op = PETSc.Mat().createPython([(n, N), (n, N)], ctx, comm=comm)
    op.setUp()
    try:
        from slepc4py import SLEPc
    except ImportError:
        SLEPc = None
    try:
        return _slepc_largest(SLEPc, op, rtol) if SLEPc is not None else _power_largest(op, template)
    finally:
        op.destroy()
        ctx.t.destroy()


def _slepc_largest(SLEPc, op, rtol):
    eps = SLEPc.EPS().create(op.getComm())
    eps.setOperators(op)
    eps.setProblemType(SLEPc.EPS.ProblemType.NHEP)
    eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_REAL)
    eps.setDimensions(nev=1)
    eps.setTolerances(tol=rtol, max_it=10_000)
    eps.solve()
    nconv = eps.getConverged()
    value = eps.getEigenvalue(0).real if nconv else None
    eps.destroy()
    if value is None:
        raise VIError("the largest eigenvalue of M^-1 A (the CFL bound) did not converge (SLEPc)")
    return float(value)


def _power_largest(op, template, its=300):
    x, y = template.duplicate(), template.duplicate()
    x.setRandom()
    lam = 0.0
    for _ in range(its):
        x.scale(1.0 / x.norm())
        op.mult(x, y)
        lam = y.dot(x)
        y.copy(x)
    x.destroy()
    y.destroy()
    return float(lam)
