"""The frictional step solver on rows (sdm_dolfinx.solvers.friction_rows): its conditions on y = R x, a
sparse matrix's rows, rather than on dofs (friction on the weighted gap).

With R square and invertible the row problem

    K x = b + R^T r,   conditions of Signorini and friction on y = R x and r

is the dof problem K' y = b' + r with K' = R^-T K R^-1, b' = R^-T b, in the unknowns y: so the row
solver's R x must be the dof solver's y, and its multipliers the dof solver's reactions. Checked on the
chain of blocks of tests/unit/test_friction_solver.py (t and n coupled, every contact state reachable)
with rows that average each block with its neighbours (weights 0.2, 0.6, 0.2; the same weights on the
tangential component, as the weighted gap's), Tresca and Coulomb, two steps, against the dof solver on
(K', b') and against the enumeration of every contact state there; 1 and 2 ranks (a row reads its
neighbours' dofs, on another rank at the partition).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import scipy.sparse

from sdm_dolfinx.solvers.friction_newton import FrictionalNewton
from sdm_dolfinx.solvers.friction_rows import rows_matrix

from test_friction_solver import CHAIN_LOADS, RTOL, Blocks, chain_matrix, enumerate_solutions

COMM = MPI.COMM_WORLD


def averaging(m):
    """The (m x m) weights: 0.6 on the block, 0.2 on each neighbour, rows summing to 1 (the ends: 0.75, 0.25)."""
    W = 0.6 * np.eye(m) + 0.2 * (np.eye(m, k=1) + np.eye(m, k=-1))
    return W / W.sum(axis=1, keepdims=True)


def normal_rows(p, W):
    """The PETSc matrix of this rank's normal rows G_i = sum_j W_ij e_(n_j) (K's column layout)."""
    sub = scipy.sparse.csr_matrix(np.kron(W[p.lo:p.hi], np.array([[0.0, 1.0]])))
    G = PETSc.Mat().createAIJ(((p.hi - p.lo, p.m), (2 * (p.hi - p.lo), 2 * p.m)),
                              csr=(sub.indptr.astype(PETSc.IntType), sub.indices.astype(PETSc.IntType), sub.data),
                              comm=COMM)
    G.assemble()
    return G


def solver(p, law, coef, rows=None):
    kw = dict(law="tresca", threshold=coef) if law == "tresca" else dict(law="coulomb", mu=coef, coulomb="newton")
    return FrictionalNewton(p.K, p.ndofs, p.tdofs, p.lb, rows=rows, **kw)


@pytest.mark.mpi
@pytest.mark.parametrize("loads", range(len(CHAIN_LOADS)))
@pytest.mark.parametrize("law,coef", [("tresca", 0.1), ("tresca", 0.3), ("coulomb", 0.2), ("coulomb", 0.5)])
def test_rows_are_the_dof_problem_in_the_rows_variables(loads, law, coef):
    F, P = CHAIN_LOADS[loads]
    m, lb = 3, [0.0, -0.1, 0.05]
    Kg = chain_matrix(m)
    W = averaging(m)
    Rsq = np.kron(W, np.eye(2))                         # y = R x, (t_i, n_i) interleaved as the dofs
    Rinv = np.linalg.inv(Rsq)
    Kp = Rinv.T @ Kg @ Rinv
    rows = Blocks(Kg, F, P, lb=lb)
    G = normal_rows(rows, W)
    mine = solver(rows, law, coef, rows_matrix(G, 1, (0,), COMM))
    ref_p = Blocks(Kp, F, P, lb=lb)
    ref = solver(ref_p, law, coef)
    xref = np.zeros(m)
    for step in range(2):
        bp = Rinv.T @ rows.bg
        ref_p.load(bp[0::2], -bp[1::2])
        mine.solve(rows.b, rows.x, xref[rows.lo:rows.hi])
        ref.solve(ref_p.b, ref_p.x, xref[ref_p.lo:ref_p.hi])
        y = Rsq @ rows.gather(rows.x.array)
        y_ref = ref_p.gather(ref_p.x.array)
        scale = np.max(np.abs(y_ref))
        assert np.max(np.abs(y - y_ref)) <= RTOL * scale, (y, y_ref)
        enum = enumerate_solutions(Kp, bp, np.asarray(lb), xref, law, coef)
        assert len(enum) == 1 and np.max(np.abs(y - enum[0])) <= RTOL * scale
        force = np.max(np.abs(rows.bg))
        assert np.max(np.abs(rows.gather(mine.lam) - ref_p.gather(ref.lam))) <= RTOL * force
        assert np.max(np.abs(rows.gather(mine.lam_t) - ref_p.gather(ref.lam_t))) <= RTOL * force
        # the reactions reach the body as R^T r: K x - b there
        r = np.ravel(np.column_stack([rows.gather(mine.lam_t), rows.gather(mine.lam)]))
        assert np.max(np.abs(Kg @ rows.gather(rows.x.array) - rows.bg - Rsq.T @ r)) <= RTOL * force
        xref = y[0::2].copy()
        rows.load(-0.5 * np.asarray(F), P)              # pressed as before, pushed back by half
    for o in (mine, ref, rows, ref_p, G):
        o.destroy()
