"""The augmented P2/P1 step matrix: a sparser matrix to factorise instead of K.

For P2/P1 with a lumped C, K = alpha^2 B^T D^-1 B + A is much denser than A and B (M couples
every P2 dof with its P1 vertex patches' neighbours); [A, alpha B^T; alpha B, -D] has K as
the Schur complement of its first block and a fraction of K's fill when factorised.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np


def augmented_matrix(A, B, c_lumped, alpha, ddofs, symmetric=True):
    """[A, alpha B^T; alpha B, -D] with D = diag(c_lumped), Dirichlet dofs of A eliminated (``symmetric``:
    A is, and the matrix is flagged so; a finite-strain tangent is not).

    Its Schur complement on the first block is K = A + alpha^2 B^T D^-1 B = alpha^2 M + A,
    the step matrix of the M formulation, so ``K x = r`` is ``aug [x; y] = [r; 0]``. For
    P2/P1, M couples every P2 dof with its P1 vertex patches' neighbours (46 nonzeros per
    row and component against A's 11): ``aug`` has less than half K's nonzeros and its
    factor a fraction of K's fill. Rows owned by a rank: its rows of K, then of D.
    """
    comm = A.getComm()
    rows = (A.getOwnershipRange()[0] + np.asarray(ddofs, dtype=np.int32)).astype(np.int32)
    A0 = A.copy()
    A0.zeroRowsColumns(rows, 1.0)
    B0 = B.copy()
    keep = B0.createVecRight()
    keep.set(1.0)
    keep.array[np.asarray(ddofs, dtype=np.int32)] = 0.0
    B0.diagonalScale(R=keep)                  # Dirichlet columns of B removed
    B0.scale(alpha)
    Bt = B0.transpose(PETSc.Mat())
    D = PETSc.Mat().createAIJ((B.getSizes()[0], B.getSizes()[0]), nnz=(1, 0), comm=comm)
    D.setUp()
    d = c_lumped.copy()
    d.scale(-1.0)
    D.setDiagonal(d)
    D.assemble()
    nest = PETSc.Mat().createNest([[A0, Bt], [B0, D]], comm=comm)
    aug = nest.convert("aij", PETSc.Mat())
    aug.setOption(PETSc.Mat.Option.SYMMETRIC, bool(symmetric))
    for m in (nest, A0, B0, Bt, D, keep, d):
        m.destroy()
    return aug


#: :func:`sparse_factor_matrix` only from this many rows of K: below, factorising K is cheap
#: anyway, and K's Cholesky factorisation propagates less round-off (1 and 2 ranks agree to
#: 1e-12 over the 300 steps of the membrane P2/P1 test, 2e-10 through the augmented matrix)
AUG_MIN_ROWS = 20_000


def sparse_factor_matrix(K, A, B, c_lumped, alpha, ddofs, ratio=0.6, min_rows=None, symmetric=True):
    """:func:`augmented_matrix` when K has at least ``min_rows`` (:data:`AUG_MIN_ROWS`) rows and the
    augmented matrix less than ``ratio`` times K's nonzeros, else None."""
    if K.getSize()[0] < (AUG_MIN_ROWS if min_rows is None else min_rows):
        return None
    aug = augmented_matrix(A, B, c_lumped, alpha, ddofs, symmetric)
    comm = K.getComm().tompi4py()
    local = PETSc.Mat.InfoType.LOCAL
    nz_aug = comm.allreduce(aug.getInfo(local)["nz_used"], op=MPI.SUM)
    nz_K = comm.allreduce(K.getInfo(local)["nz_used"], op=MPI.SUM)
    if nz_aug < ratio * nz_K:
        return aug
    aug.destroy()
    return None
