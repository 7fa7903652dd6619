"""The gap-row Newton (solvers/gap_newton.py) on hand-made problems: the KKT conditions of

    min 1/2 x^T K x - b^T x   subject to   G x >= g

hold at its solution: G x >= g, lam >= 0, lam . (G x - g) = 0 and K x - b = G^T lam, to the
solver's tolerance (asserted 1e-8 of the data's scale, the complementarity test's rtol being 1e-10
of max|b|), with at least one row active and one inactive (so both branches are exercised). K is
a random SPD matrix (a 1-D Laplacian plus a random diagonal, distributed over the ranks), G either
node rows (two dofs of a "node" with a unit normal each, the obstacle case) or a distributed
matrix whose rows read several dofs, some on another rank (the weighted case). The node rows'
normals change between two solves with the same solver (its cached columns serve both).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest

from sdm_dolfinx.solvers.gap_newton import GapNewton

COMM = MPI.COMM_WORLD
N = 40                                      # global size (20 "nodes" of 2 dofs)


def _K():
    K = PETSc.Mat().createAIJ([N, N], nnz=3, comm=COMM)
    r0, r1 = K.getOwnershipRange()
    rng = np.random.default_rng(1)
    diag = 2.0 + rng.random(N)
    for i in range(r0, r1):
        K.setValue(i, i, diag[i] + 2.0)
        if i > 0:
            K.setValue(i, i - 1, -1.0)
        if i < N - 1:
            K.setValue(i, i + 1, -1.0)
    K.assemble()
    return K


def _b(K, seed):
    b = K.createVecLeft()
    r0, r1 = K.getOwnershipRange()
    b.array[:] = np.random.default_rng(seed).standard_normal(N)[r0:r1] - 1.0
    return b


def _check(K, b, x, Gx, g, lam, GTlam):
    r = K.createVecLeft()
    K.mult(x, r)
    r.axpy(-1.0, b)
    scale = max(COMM.allreduce(float(np.max(np.abs(b.array), initial=0.0)), op=MPI.MAX), 1.0)
    tol = 1e-8 * scale
    assert COMM.allreduce(float(np.max(np.abs(r.array - GTlam), initial=0.0)), op=MPI.MAX) <= tol
    assert COMM.allreduce(float(np.min(Gx - g, initial=np.inf)), op=MPI.MIN) >= -tol
    assert COMM.allreduce(float(np.min(lam, initial=np.inf)), op=MPI.MIN) >= -tol
    assert COMM.allreduce(float(np.max(np.abs(lam * (Gx - g)), initial=0.0)), op=MPI.MAX) <= tol * scale
    n_active = COMM.allreduce(int(np.count_nonzero(lam > tol)), op=MPI.SUM)
    n_rows = COMM.allreduce(len(lam), op=MPI.SUM)
    assert 0 < n_active < n_rows


def _matrix_rows(K):
    """(G, g): rows reading three dofs each, one of another rank at the partition; some rows far from binding."""
    r0, r1 = K.getOwnershipRange()
    m_loc = (r1 - r0) // 2
    rows0 = COMM.exscan(m_loc) or 0
    M = COMM.allreduce(m_loc, op=MPI.SUM)
    G = PETSc.Mat().createAIJ([(m_loc, M), (r1 - r0, N)], nnz=3, comm=COMM)
    for k in range(m_loc):                   # row i averages dofs 2i, 2i + 1, 2i + 2 (the last of another rank)
        i = rows0 + k
        for j, w in ((2 * i, 0.25), (2 * i + 1, 0.5), ((2 * i + 2) % N, 0.25)):
            G.setValue(i, j, w)
    G.assemble()
    return G, np.where(np.arange(m_loc) % 3 == 0, -3.0, 0.15)


def test_node_rows_with_turning_normals_satisfy_the_kkt_conditions():
    K = _K()
    r0, r1 = K.getOwnershipRange()
    first = r0 + (r0 % 2)                   # whole "nodes" (pairs of dofs) owned here
    dofs = np.array([[i - r0, i + 1 - r0] for i in range(first, r1 - 1, 2)], dtype=np.int32).reshape(-1, 2)
    solver = GapNewton(K, dofs)
    for angle in (0.3, 1.1):                # the same solver, the normals turned between the solves
        theta = angle + 0.1 * np.arange(len(dofs))
        coef = np.column_stack([np.cos(theta), np.sin(theta)])
        g = np.where(np.arange(len(dofs)) % 3 == 0, -3.0, 0.3)      # some rows far from binding
        solver.set_rows(coef, g)
        b = _b(K, 2)
        x = K.createVecRight()
        solver.solve(b, x)
        Gx = solver.row_values(x.array_r)
        GTlam = np.zeros(r1 - r0)
        np.add.at(GTlam, dofs.reshape(-1), (coef * solver.lam[:, None]).reshape(-1))
        _check(K, b, x, Gx, g, solver.lam, GTlam)
    solver.destroy()


def test_matrix_rows_reading_other_ranks_dofs_satisfy_the_kkt_conditions():
    K = _K()
    G, g = _matrix_rows(K)
    solver = GapNewton(K, G=G)
    solver.set_rows(None, g)
    b = _b(K, 3)
    x = K.createVecRight()
    solver.solve(b, x)
    Gx = solver.row_values(x.array_r)
    lam_vec, GTlam = G.createVecLeft(), G.createVecRight()
    lam_vec.array[:] = solver.lam
    G.multTranspose(lam_vec, GTlam)
    _check(K, b, x, Gx, g, solver.lam, GTlam.array_r)
    solver.destroy()


def test_node_rows_or_a_matrix_one_of_them():
    with pytest.raises(ValueError, match="one of them"):
        GapNewton(_K())


@pytest.mark.parametrize("kind", ["node", "matrix", "penalty"])
def test_the_krylov_fallback_solves_the_same_step_as_the_cached_columns(kind):
    """With at most 4 cached columns every active set beyond them is solved by CG on the Schur
    complement G_A K^-1 G_A^T (one solve per product): the same x and multipliers as the dense system on
    cached columns, to CG's tolerance (asserted 1e-9 of their scale; measured ~1e-14), and the KKT
    conditions hold; node rows, matrix rows reading other ranks' dofs, and the penalty's compliances."""
    K = _K()
    r0, r1 = K.getOwnershipRange()
    if kind == "node":
        first = r0 + (r0 % 2)
        dofs = np.array([[i - r0, i + 1 - r0] for i in range(first, r1 - 1, 2)], dtype=np.int32).reshape(-1, 2)
        theta = 0.3 + 0.1 * np.arange(len(dofs))
        coef = np.column_stack([np.cos(theta), np.sin(theta)])
        g = np.where(np.arange(len(dofs)) % 3 == 0, -3.0, 0.3)
        make = lambda cap: GapNewton(K, dofs, max_columns=cap)                 # noqa: E731
    else:
        G, g = _matrix_rows(K)
        coef = None
        k = np.full(len(g), 50.0) if kind == "penalty" else None
        make = lambda cap: GapNewton(K, G=G, max_columns=cap, stiffness=k)     # noqa: E731
    out = {}
    for cap in (4, 1000):
        solver = make(cap)
        solver.set_rows(coef, g)
        b = _b(K, 2)
        x = K.createVecRight()
        solver.solve(b, x)
        out[cap] = (x.array_r.copy(), solver.lam.copy(), solver.rows.krylov)
        if kind != "penalty":
            Gx = solver.row_values(x.array_r)
            if kind == "node":
                GTlam = np.zeros(r1 - r0)
                np.add.at(GTlam, dofs.reshape(-1), (coef * solver.lam[:, None]).reshape(-1))
            else:
                lam_vec, GT = G.createVecLeft(), G.createVecRight()
                lam_vec.array[:] = solver.lam
                G.multTranspose(lam_vec, GT)
                GTlam = GT.array_r.copy()
            _check(K, b, x, Gx, g, solver.lam, GTlam)
        solver.destroy()
    (x4, lam4, used), (x0, lam0, dense) = out[4], out[1000]
    assert COMM.allreduce(used, op=MPI.LOR) and not dense
    scale = COMM.allreduce(float(np.max(np.abs(x0), initial=0.0)), op=MPI.MAX)
    assert COMM.allreduce(float(np.max(np.abs(x4 - x0), initial=0.0)), op=MPI.MAX) <= 1e-9 * scale
    lscale = COMM.allreduce(float(np.max(np.abs(lam0), initial=0.0)), op=MPI.MAX)
    assert COMM.allreduce(float(np.max(np.abs(lam4 - lam0), initial=0.0)), op=MPI.MAX) <= 1e-9 * lscale


def test_repeated_active_rows_split_their_force_equally_whatever_their_order():
    """Two rows that are the same constraint (the two passes of a node-to-surface contact on matching
    meshes) make S = G_A K^-1 G_A^T singular: the multipliers are the minimum-norm ones, each repeated
    row taking its share equally, in any order of the rows; S mu = r holds."""
    from sdm_dolfinx.solvers.gap_rows import active_multipliers
    rng = np.random.default_rng(3)
    A = rng.random((4, 4))
    G = np.vstack([A[:3], A[1]])                          # row 3 repeats row 1
    S = G @ np.linalg.inv(np.diag(2.0 + rng.random(4))) @ G.T
    r = G @ rng.random(4)
    mu = active_multipliers(S, r)
    assert np.max(np.abs(S @ mu - r)) <= 1e-12 * np.max(np.abs(r))
    assert mu[3] == pytest.approx(mu[1], rel=1e-12)
    order = np.array([3, 0, 2, 1])
    np.testing.assert_allclose(active_multipliers(S[np.ix_(order, order)], r[order]), mu[order], rtol=1e-12)
    # independent rows: the one solution
    np.testing.assert_allclose(active_multipliers(S[:3, :3], r[:3]), np.linalg.solve(S[:3, :3], r[:3]), rtol=1e-12)


def test_repeated_active_rows_asking_for_different_gaps_are_refused():
    from sdm_dolfinx.solvers.base import VIError
    from sdm_dolfinx.solvers.gap_rows import active_multipliers
    S = np.array([[2.0, 2.0], [2.0, 2.0]])
    with pytest.raises(VIError, match="linearly dependent"):
        active_multipliers(S, np.array([1.0, 1.5]))
