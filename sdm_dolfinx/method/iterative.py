"""What the iterative linear strategies ``cg-gamg`` and ``cg-pmg`` need from the discretisation: the
rigid body modes of W^h (GAMG's near-nullspace), a sparse matrix P ~ K to build the AMG hierarchy from
(and whose diagonal is K's), a cheap product with K; for ``cg-pmg`` the interpolation from the vertices'
P1 into W^h = P2 and the Galerkin coarse operator I^T K I.

**cg-pmg** (a two-level p-multigrid): GAMG on P sees the P2 elasticity operator through a sparse
stand-in and needs more CG iterations as the mesh is refined (the ball, levels 1-4: 43, 47, 63, 69 to
1e-10 from zero, random right-hand side); two Chebyshev/Jacobi steps on K itself smooth the P2 part, and
GAMG on the P1 Galerkin operator I^T K I (the P1 elasticity problem with its rigid body modes, where
smoothed aggregation works well) the rest: 17, 18, 18, 19 iterations (bench/README.md).

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
import weakref

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx.method import masses, step_matrix
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.solvers.active_set import PMAT, PMG_COARSE, PMG_INTERPOLATION, PRODUCT



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


class Product:
    """y = K x with K = c_M B^T D^-1 B + c_A A, the rows and columns ``dd`` (the Dirichlet dofs) the identity
    (PETSc python Mat context; its diagonal from A and B, :func:`~.masses.diagonal`). Four passes over the
    data when there are no Dirichlet dofs: A x (:func:`blocked`), B x, its scaling by c_M / D and
    y += B^T (...) in one product."""

    def __init__(self, d, c_M, c_A, dd=None):
        self.d, self.A, self.B, self.cM, self.cA = d, blocked(d), d.B, c_M, c_A
        self.dd = np.asarray(d.ddofs if dd is None else dd, dtype=np.int32)
        self.any_dd = d.comm.allreduce(len(self.dd), op=MPI.SUM) > 0      # the same branch on every rank
        self.x0, self.h = d.A.createVecRight(), d.B.createVecLeft()
        self.scale = d.c_lumped.copy()              # c_M / D
        self.scale.reciprocal()
        self.scale.scale(c_M)
        self.mass = masses.through_b(d)             # M x alone (energies, momenta)
        self._diagonal = None

    def mult(self, mat, x, y):
        x0 = x
        if self.any_dd:
            x.copy(self.x0)
            self.x0.array[self.dd] = 0.0
            x0 = self.x0
        self.A.mult(x0, y)
        if self.cA != 1.0:
            y.scale(self.cA)
        self.B.mult(x0, self.h)
        self.h.pointwiseMult(self.h, self.scale)
        self.B.multTransposeAdd(self.h, y, y)
        if self.any_dd:
            y.array[self.dd] = x.array_r[self.dd]

    def multTranspose(self, mat, x, y):
        self.mult(mat, x, y)

    def getDiagonal(self, mat, out):
        if self._diagonal is None:          # asked for by the preconditioner's P and the Alart-Curnier parameter
            self._diagonal = diagonal(self.d, self.cM, self.cA, self.dd)
        self._diagonal.copy(out)


#: Discretisation -> its A in PETSc's block format (:func:`blocked`), made once
_BLOCKED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def blocked(d):
    """A of Discretisation ``d`` for products: for a vector W^h a copy in PETSc's block format (BAIJ), 3.5 times
    faster than dolfinx's AIJ (the ball, level 4, 107k dofs, bs 3: 3.7 ms against 12.7 ms; B's block copy is not
    faster: 3.0 ms against 2.2 ms), made once per discretisation; else A itself."""
    if d.A.getBlockSize() == 1:
        return d.A
    if d not in _BLOCKED:
        _BLOCKED[d] = compat.assemble_matrix_baij(d.form(d._a_ufl))     # A assembled again, blocked
    return _BLOCKED[d]


def diagonal(d, c_M, c_A, dd):
    """c_A diag(A) + c_M diag(M) of Discretisation ``d``, 1 at the rows ``dd``."""
    out = d.A.getDiagonal()
    out.scale(c_A)
    out.axpy(c_M, masses.diagonal(d))
    out.array[np.asarray(dd, dtype=np.int32)] = 1.0
    return out


def refusal(d, linear, block):
    """Why linear strategy ``linear`` cannot run on Discretisation ``d`` (``block``: the consistent mass's
    (U, V) block system), one line, or None: ``cg-pmg``'s coarsening needs the lumped M formulation and a
    P2 W^h."""
    if linear != "cg-pmg":
        return None
    if block:
        return ("linear strategy cg-pmg coarsens the step matrix of the lumped M formulation, and mass "
                "'consistent' solves the (U, V) block system: use mass 'lumped' or choose cg-gamg")
    return coarse_refusal(d)


def prefer_pmg(d, linear, why, block):
    """(strategy, reason) of ``auto``: its ``cg-gamg`` becomes ``cg-pmg`` where W^h = P2 can be coarsened."""
    if linear == "cg-gamg" and refusal(d, "cg-pmg", block) is None:
        return "cg-pmg", (f"{why}; cg-pmg, as W^h = P2 coarsens to the vertices' P1 (the ball: 3.3-3.8 times "
                          f"faster than cg-gamg per contact step, bench/README.md)")
    return linear, why


def coarse_refusal(d):
    """Why ``cg-pmg`` cannot run on Discretisation ``d`` (one line), or None: its coarse space is the
    vertices' P1, so W^h must be the Lagrange P2 (P2/P1, P2/P2)."""
    family, degree = d.pair.w
    if family == "P+" or degree != 2:
        return (f"linear strategy cg-pmg coarsens W^h = P2 to P1 at the vertices, and pair {d.pair.name} has "
                f"W^h = {'P1 + bubble' if family == 'P+' else f'P{degree}'}: choose cg-gamg")
    return None


def coarse_operator(d, interpolation, c_M, c_A):
    """I^T K I for K = c_M B^T D^-1 B + c_A A with the Dirichlet rows and columns the identity, from A and
    the H x P1 matrix B_0 I (B_0: B with the Dirichlet columns zeroed), never forming K:
    I^T K I = I^T A_0 I + c_M (B_0 I)^T D^-1 (B_0 I), A_0 = c_A A with the Dirichlet rows and columns the
    identity."""
    A0 = d.A.copy()
    A0.scale(c_A)
    coarse = step_matrix.identity_rows(A0, d.ddofs).PtAP(interpolation)
    A0.destroy()
    free = d.A.createVecRight()
    free.set(1.0)
    free.array[np.asarray(d.ddofs, dtype=np.int32)] = 0.0
    B0 = d.B.copy()
    B0.diagonalScale(R=free)
    BI = B0.matMult(interpolation)
    B0.destroy()
    scaled = BI.copy()
    cinv = d.c_lumped.copy()
    cinv.reciprocal()
    scaled.diagonalScale(L=cinv)
    BIt = BI.transpose(PETSc.Mat())
    mass = BIt.matMult(scaled)
    for m in (BI, scaled, BIt):
        m.destroy()
    coarse.axpy(c_M, mass, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    mass.destroy()
    return coarse


def _coarse(K, d, coefficients, keep):
    """Compose with K the interpolation I from the vertices' P1 into W^h and the Galerkin coarse operator
    I^T K I with the P1 rigid body modes (``cg-pmg``: :func:`~sdm_dolfinx.solvers.active_set.InactiveSetSolver.
    _pmg_preconditioner`): :func:`coarse_operator`, or K's own PtAP when K is not c_M B^T D^-1 B + c_A A."""
    refusal = coarse_refusal(d)
    if refusal:
        raise DiscretisationError(refusal)
    interpolation = compat.interpolation_matrix(d.P1, d.W)
    if coefficients is not None and d.B is not None and d.c_lumped is not None:
        coarse = coarse_operator(d, interpolation, *coefficients)
    else:
        coarse = K.PtAP(interpolation)
    ns = rigid_body_modes(d.P1)
    if ns is not None and ns.getVecs()[0].getLocalSize() == coarse.getLocalSize()[0]:
        coarse.setNearNullSpace(ns)
    K.compose(PMG_INTERPOLATION, interpolation)
    K.compose(PMG_COARSE, coarse)
    keep += [interpolation, coarse, ns]


def attach(K, d, coefficients, coarse=False):
    """Compose with the step matrix K (Dirichlet rows eliminated; assembled, or the operator of
    :mod:`.matrix_free`) of Discretisation ``d`` its near-nullspace, a sparse P = c_A A + c_M diag(M)
    and, when M x is cheaper through B (:func:`~sdm_dolfinx.method.masses.product`) and K is assembled,
    the product of :class:`Product` (see the module); with ``coarse`` (``cg-pmg``) also the P1
    interpolation and the coarse operator of :func:`_coarse`. ``coefficients``: (c_M, c_A) of
    K = c_M M + c_A A, or None (another step matrix: P = K, no product). Returns the objects to keep
    alive."""
    ns = rigid_body_modes(d.W)
    if ns is not None and ns.getVecs()[0].getLocalSize() != K.getLocalSize()[0]:
        ns = None
    keep = [ns]
    free = K.getType() == PETSc.Mat.Type.PYTHON         # matrix-free: K is the product
    if coefficients is None or (not free and d.M is None):
        P = K
    else:
        c_M, c_A = coefficients
        P = d.A.copy()
        P.scale(c_A)
        step_matrix.identity_rows(P, d.ddofs)
        P.setDiagonal(K.getDiagonal())              # K's (the operator's: from A and B, not M)
        K.compose(PMAT, P)
        keep.append(P)
        if not free and d.mass_product() != d.M.mult:         # M = B^T D^-1 B much denser than B
            prod = PETSc.Mat().createPython(K.getSizes(), Product(d, c_M, c_A), comm=K.getComm())
            prod.setUp()
            K.compose(PRODUCT, prod)
            keep.append(prod)
    if ns is not None:
        P.setNearNullSpace(ns)
    if coarse:
        _coarse(K, d, coefficients, keep)
    return keep
