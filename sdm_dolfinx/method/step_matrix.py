"""The step matrix of a time scheme: K = c_M M + c_A A (M formulation) or the (U, V) block
matrix, and its Dirichlet elimination (identity rows and columns, lifting z = K g).

For the paper's schemes c_M = alpha^2 and c_A = 1 (alpha = 2/dt midpoint, 1/dt backward
Euler); Newmark's family has c_M = 1/(beta dt^2) and c_A = 1 + alpha_HHT; an explicit scheme
c_A = 0 (:mod:`sdm_dolfinx.schemes`).
"""
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx import compat
from sdm_dolfinx.problems import density

#: the masses whose sparsity pattern contains A's (M = B^T C^-1 B and the consistent mass of
#: W^h): K = c_M M + c_A A is added in place into M's pattern; the others (a lumped or
#: redistributed mass may hold fewer nonzeros) take A's pattern too
PATTERN_HOLDS_A = ("standard", "diagonal", "lumped")


def combination(d, c_M, c_A):
    """c_M M + c_A A, a new matrix (``d``: the Discretisation; its M formed)."""
    K = d.M.copy()
    K.scale(c_M)
    if c_A:
        structure = (PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN if d.mass in PATTERN_HOLDS_A
                     else PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        K.axpy(c_A, d.A, structure=structure)
    return K


def block_matrix(d, alpha):
    """[A  alpha B^T; alpha B  -C], the (U, V) block system of the consistent C (M never formed)."""
    p, W, H = d.problem, d.W, d.H
    u, w = ufl.TrialFunction(W), ufl.TestFunction(W)
    v, q = ufl.TrialFunction(H), ufl.TestFunction(H)
    rho = density.form(p)
    al = fem.Constant(p.mesh, PETSc.ScalarType(alpha))
    forms = [[d.form(p.a(u, w)), d.form(al * rho * ufl.inner(v, w) * ufl.dx)],       # the degree of A, B, C
             [d.form(al * rho * ufl.inner(u, q) * ufl.dx), d.form(-rho * ufl.inner(v, q) * ufl.dx)]]
    return compat.assemble_matrix_block(forms)


def eliminate(K, d):
    """(K with the Dirichlet rows and columns of ``d.ddofs`` replaced by the identity, gsys the
    vector of the Dirichlet values g, lift = K g) for the constant values g of ``d``."""
    gsys = K.createVecRight()
    gsys.array[d.ddofs] = d.g.x.array[d.ddofs]
    lift = K.createVecLeft()
    K.mult(gsys, lift)
    K0 = K.copy()
    rows = K.getOwnershipRange()[0] + d.ddofs
    K0.zeroRowsColumns(rows.astype(np.int32), 1.0)
    return K0, gsys, lift


def identity_rows(K, local_rows):
    """K with the owned rows and columns ``local_rows`` replaced by the identity, in place."""
    rows = (K.getOwnershipRange()[0] + np.asarray(local_rows, dtype=np.int64)).astype(np.int32)
    K.zeroRowsColumns(rows, 1.0)
    return K
