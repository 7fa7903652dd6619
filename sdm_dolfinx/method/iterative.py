"""What the iterative linear strategy ``cg-gamg`` needs from the discretisation: the rigid body
modes of W^h (GAMG's near-nullspace), a sparse matrix P ~ K to build the AMG hierarchy from, and
a cheap product with K.

For P2/P1 with a lumped C, M = B^T D^-1 B couples every P2 dof with its P1 vertex patches'
neighbours: the 3-D ball's K has ~590 nonzeros per row against A's ~76 (level 1: 3.9 M
against 0.5 M), so one K x costs 16 ms where A x + B^T (D^-1 (B x)) costs 2.6 ms, and GAMG on K
costs 75 ms per CG iteration (its Chebyshev smoothing is products with K). Measured (level 1,
CG to 1e-10 from zero, random right-hand side): GAMG built on K, 26 iterations, 1.95 s; built
on P = c_A A + c_M diag(M) with the smoothing on the cheap product, 39 iterations, 0.29 s
(level 2: 43 iterations, 1.7 s against 26 and 6.9 s). The coarse spaces come from P, the
smoothing and the Krylov method see K itself, so the solution is K's.

:func:`attach` composes them with K (``K.compose``): the solvers find them with ``K.query``
(:mod:`sdm_dolfinx.solvers.active_set`), so no solver signature changes.
"""
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.solvers.active_set import PMAT, PRODUCT



def rigid_body_modes(W):
    """The rigid body modes of ``W`` as a :class:`PETSc.NullSpace` of orthonormal vectors in W's
    layout (owned dofs, blocked), or None.

    A vector space of block size gdim has gdim translations and gdim (gdim - 1) / 2 rotations
    x -> x_i e_j - x_j e_i from the coordinates of W's dof nodes (3 modes in 2-D, 6 in 3-D, as
    dolfinx v0.5.2's ``demo_elasticity.py`` ``build_nullspace``); a scalar space has the
    constants. None for a space whose dof coordinates dolfinx cannot tabulate (an enriched
    element): GAMG then takes the constants per block.
    """
    imap, bs = W.dofmap.index_map, W.dofmap.index_map_bs
    n = imap.size_local
    gdim = W.mesh.geometry.dim
    if bs not in (1, gdim):
        return None
    try:
        x = W.tabulate_dof_coordinates()[:n, :gdim]
    except Exception:           # e.g. an enriched element (P1 + bubble): no point evaluation
        return None
    modes = [np.zeros((n, bs)) for _ in range(bs)]
    for i in range(bs):
        modes[i][:, i] = 1.0        # translations (the constant when bs = 1)
    for i in range(gdim if bs > 1 else 0):
        for j in range(i + 1, gdim):
            r = np.zeros((n, bs))
            r[:, i], r[:, j] = -x[:, j], x[:, i]            # rotation in the (x_i, x_j) plane
            modes.append(r)
    vecs = []
    for m in modes:             # Gram-Schmidt with global dot products
        v = PETSc.Vec().createMPI((n * bs, PETSc.DECIDE), bsize=bs, comm=W.mesh.comm)
        v.array[:] = m.ravel()
        for q in vecs:
            v.axpy(-v.dot(q), q)
        v.normalize()
        vecs.append(v)
    return PETSc.NullSpace().create(vectors=vecs, comm=W.mesh.comm)


class _Product:
    """y = K x with K = c_M M + c_A A (M x by the discretisation's fastest mass product),
    Dirichlet rows and columns the identity (PETSc python Mat context)."""

    def __init__(self, d, mass_mult, c_M, c_A):
        self.A, self.mass, self.cM, self.cA = d.A, mass_mult, c_M, c_A
        self.dd = np.asarray(d.ddofs, dtype=np.int32)
        self.w, self.x0 = d.A.createVecLeft(), d.A.createVecRight()

    def mult(self, mat, x, y):
        x.copy(self.x0)
        self.x0.array[self.dd] = 0.0
        self.A.mult(self.x0, y)
        y.scale(self.cA)
        self.mass(self.x0, self.w)
        y.axpy(self.cM, self.w)
        y.array[self.dd] = x.array_r[self.dd]


def attach(K, d, coefficients):
    """Compose with the step matrix K (Dirichlet rows eliminated) of Discretisation ``d`` its
    near-nullspace, a sparse P = c_A A + c_M diag(M) and, when M x is cheaper through B
    (:func:`~sdm_dolfinx.method.masses.product`), the product of :class:`_Product` (see the
    module). ``coefficients``: (c_M, c_A) of K = c_M M + c_A A, or None (another step matrix:
    P = K, no product). Returns the objects to keep alive."""
    ns = rigid_body_modes(d.W)
    if ns is not None and ns.getVecs()[0].getLocalSize() != K.getLocalSize()[0]:
        ns = None
    keep = [ns]
    if coefficients is None or d.M is None:
        P = K
    else:
        c_M, c_A = coefficients
        P = d.A.copy()
        P.scale(c_A)
        dm = d.M.getDiagonal()
        dm.scale(c_M)
        P.setDiagonal(dm, addv=True)
        rows = (K.getOwnershipRange()[0] + np.asarray(d.ddofs, dtype=np.int64)).astype(np.int32)
        P.zeroRowsColumns(rows, 1.0)
        K.compose(PMAT, P)
        keep.append(P)
        mass_mult = d.mass_product()
        if mass_mult != d.M.mult:         # M = B^T D^-1 B much denser than B: through B
            prod = PETSc.Mat().createPython(K.getSizes(), _Product(d, mass_mult, c_M, c_A),
                                            comm=K.getComm())
            prod.setUp()
            K.compose(PRODUCT, prod)
            keep.append(prod)
    if ns is not None:
        P.setNearNullSpace(ns)
    return keep
