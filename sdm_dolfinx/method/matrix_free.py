"""The step matrix K = c_M M + c_A A as an operator, never assembled (the multigrid strategies).

For P2/P1 with a lumped C, M = B^T D^-1 B couples every P2 dof with its P1 vertex patches'
neighbours: the 3-D ball's M has ~740 nonzeros per row against A's ~83 (level 4: 79 M against
8.9 M). An assembled run holds three matrices of that size (M, K = c_M M + c_A A, and K with its
Dirichlet rows and columns eliminated): 2.9 of the 3.5 GB of a level-4 ``cg-pmg`` run. The multigrid
strategies (``cg-gamg``, ``cg-pmg``) need K only through

* products: K x = c_A A x + c_M B^T (D^-1 (B x)) (:class:`~.iterative.Product`, which the assembled
  runs already use for CG and the smoothing: at level 1 it costs 2.6 ms where the assembled K x costs
  16 ms),
* its diagonal (Jacobi, the Alart-Curnier parameter): c_A diag(A) + c_M diag(M), with
  diag(M)_j = sum_i B_ij^2 / D_i (:func:`~.masses.diagonal`),
* the coarse operator of ``cg-pmg``, I^T K I = I^T A_0 I + c_M (B_0 I)^T D^-1 (B_0 I), formed from A
  and the small H x P1 matrix B_0 I (:func:`~.iterative.coarse_operator`),

so a run that needs nothing else (:func:`refusal` is None) keeps K as a PETSc python Mat and never
forms M. The solution is the assembled run's to the Krylov tolerance (``tests/solvers/test_matrix_free.py``).
"""
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.method.iterative import Product
from sdm_dolfinx.solvers.active_set import MULTIGRID_STRATEGIES


def refusal(integ, linear):
    """Why the step matrix of Integrator ``integ`` (its coefficients known) with linear strategy ``linear``
    must be assembled (a short reason), or None: it can be the operator of :func:`operator`."""
    d = integ.discretisation
    if linear not in MULTIGRID_STRATEGIES:
        return "a factorisation or a Krylov method on the assembled matrix"
    if integ.block or integ.coefficients is None or integ.coefficients[1] == 0.0:
        return "a scheme or formulation with a step matrix of its own"
    if d.B is None or d.c_lumped is None:
        return "M is not B^T D^-1 B"
    if (integ.friction is not None or integ.contact != "exact" or integ.vi_solver != "ssn" or integ.parts
            or any(r is not None for r in (d.obstacle_rows, d.body_rows, d.weighted_rows))):
        return "a step solver that reads K's entries"
    return None


def operator(d, c_M, c_A, dirichlet=True):
    """K = c_M M + c_A A of Discretisation ``d`` as a PETSc python Mat (M through B, never formed), with
    the Dirichlet rows and columns the identity (``dirichlet``) or not."""
    dd = d.ddofs if dirichlet else np.zeros(0, dtype=np.int32)
    K = PETSc.Mat().createPython(d.A.getSizes(), Product(d, c_M, c_A, dd), comm=d.comm)
    K.setUp()
    return K


def eliminate(K_full, d, c_M, c_A):
    """(K with the Dirichlet rows and columns the identity, gsys the vector of the Dirichlet values g,
    lift = K_full g), as :func:`~.step_matrix.eliminate` does for an assembled K."""
    gsys = K_full.createVecRight()
    gsys.array[d.ddofs] = d.g.x.array[d.ddofs]
    lift = K_full.createVecLeft()
    K_full.mult(gsys, lift)
    return operator(d, c_M, c_A), gsys, lift
