"""The penalty step solver on hand-made systems, without meshes.

    K x = b + P^T lam,   lam_i = k_i (lb_i - x_{c_i})_+        (solvers/penalty.py)

K is a string over a parabolic obstacle (a Laplacian plus a mass-like diagonal, SPD); its
load pushes most constrained dofs below their bounds. The reference is an independent route:
a dense Newton method on the full system (numpy, all n unknowns, Jacobian K + P^T diag(k_A) P),
not the solver's Schur complement on the constrained dofs. Run serially and under mpirun -n 2
(the matrices are distributed by rows).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import scipy.sparse
import scipy.sparse.linalg

from sdm_dolfinx.solvers import PenaltyNewton, VIError
from sdm_dolfinx.solvers.schur import SCHUR_MAX_ACTIVE

COMM = MPI.COMM_WORLD
#: the penalised equation holds to round-off: |K x - b - P^T lam| relative to the size of its terms,
#: (|K|_inf + max k) max|x| (measured 1e-15 to 2e-15; a stiff spring turns x's last bit into k eps |x|)
EQ_RTOL = 1e-12
#: agreement with the dense full-space Newton solution, relative to max|x|
X_RTOL = 1e-10


def string(n, constrained_every=1):
    """K = h^-2 tridiag(-1, 2, -1) + I, load -10, bounds a parabola around -0.3 at every
    ``constrained_every``-th dof."""
    h = 1.0 / (n + 1)
    s = np.linspace(h, 1.0 - h, n)
    K = scipy.sparse.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]) / h ** 2
    K = (K + scipy.sparse.identity(n)).tocsr()
    cglob = np.arange(0, n, constrained_every)
    lb = -0.3 + 0.2 * (s[cglob] - 0.5) ** 2
    return K, -10.0 * np.ones(n), cglob, lb


def dense_reference(K, b, cglob, lb, k, max_it=200):
    """The penalised system by Newton's method on all n unknowns (dense numpy)."""
    Kd = K.toarray()
    x = np.linalg.solve(Kd, b)
    for _ in range(max_it):
        act = x[cglob] < lb
        J = Kd.copy()
        J[cglob[act], cglob[act]] += k[act]
        rhs = b.copy()
        rhs[cglob[act]] += k[act] * lb[act]
        x_new = np.linalg.solve(J, rhs)
        if np.array_equal(x_new[cglob] < lb, act):
            return x_new
        x = x_new
    raise AssertionError("dense Newton did not converge")


def distributed(K, b, cglob, lb, k):
    """PETSc K, b, x with this rank's rows, and the owned constrained dofs, bounds, stiffnesses."""
    n = K.shape[0]
    sizes = [n // COMM.size + (r < n % COMM.size) for r in range(COMM.size)]
    lo = sum(sizes[:COMM.rank])
    hi = lo + sizes[COMM.rank]
    sub = K[lo:hi]
    csr = (sub.indptr.astype(PETSc.IntType), sub.indices.astype(PETSc.IntType), sub.data)
    A = PETSc.Mat().createAIJ(((hi - lo, n), (hi - lo, n)), csr=csr, comm=COMM)
    A.assemble()
    bv, xv = A.createVecLeft(), A.createVecRight()
    bv.array[:] = b[lo:hi]
    own = (cglob >= lo) & (cglob < hi)
    return A, bv, xv, (cglob[own] - lo).astype(np.int32), lb[own], k[own]


def solve(K, b, cglob, lb, k, krylov=None):
    """The solver's x (gathered), its lam (gathered) and info; ``krylov``, a dict, receives the
    fallback KSP's relative tolerance and norm type."""
    A, bv, xv, c, lbl, kl = distributed(K, b, cglob, lb, k)
    solver = PenaltyNewton(A, c, lbl, kl)
    try:
        xv.set(0.0)
        info = solver.solve(bv, xv)
        x = np.concatenate(COMM.allgather(xv.array.copy()))
        lam = np.concatenate(COMM.allgather(solver.lam.copy()))
        if krylov is not None:
            ksp = solver.inactive.ksp
            krylov.update(rtol=ksp.getTolerances()[0], norm=ksp.getNormType(),
                          zero_guess=not ksp.getInitialGuessNonzero())
        return x, lam, info, solver.total_linear_its
    finally:
        solver.destroy()
        for o in (A, bv, xv):
            o.destroy()


def penalised_residual(K, b, cglob, lb, k, x):
    """r = K x - b - P^T k (lb - x_c)_+ and the penalty force k (lb - x_c)_+."""
    force = k * np.maximum(lb - x[cglob], 0.0)
    r = K @ x - b
    r[cglob] -= force
    return r, force


def assert_penalised(K, b, cglob, lb, k, x, lam):
    """K x - b = P^T k (lb - x_c)_+ to round-off, and the solver's lam is that force."""
    r, force = penalised_residual(K, b, cglob, lb, k, x)
    scale = (scipy.sparse.linalg.norm(K, np.inf) + np.max(k)) * np.max(np.abs(x))
    assert np.max(np.abs(r)) <= EQ_RTOL * scale, f"equation off by {np.max(np.abs(r)) / scale:.2e}"
    assert np.max(np.abs(lam - force)) <= EQ_RTOL * scale


@pytest.mark.mpi
@pytest.mark.parametrize("stiffness", [1e2, 1e4, 1e7])
def test_penalised_equation_holds(stiffness):
    """A few dozen springs active (the Schur path): the equation holds to 1e-12 and x agrees
    with the dense full-space Newton solution."""
    K, b, cglob, lb = string(120, constrained_every=3)
    k = stiffness * (1.0 + 0.5 * np.sin(np.arange(len(cglob))))       # non-uniform stiffnesses
    x, lam, info, _ = solve(K, b, cglob, lb, k)
    assert_penalised(K, b, cglob, lb, k, x, lam)
    xref = dense_reference(K, b, cglob, lb, k)
    assert np.max(np.abs(x - xref)) <= X_RTOL * np.max(np.abs(xref))
    n_pen = int(np.count_nonzero(xref[cglob] < lb))
    assert info["n_active"] == n_pen and 5 <= n_pen < len(cglob)


@pytest.mark.mpi
def test_large_active_set_falls_back_to_krylov():
    """More springs active than the Schur strategy takes: CG on K_A = K + P^T diag(k_A) P
    preconditioned by K's factorisation. That path promises what its KSP was given, not
    round-off: CG in PETSc's default (preconditioned) norm from a zero guess stops when
    |K^-1 r|_2 <= rtol |K^-1 rhs|_2, rhs = b + P^T (k_A lb_A), r = rhs - K_A x. The unpreconditioned
    residual is then only bounded by |K| times that (measured 1e-11 of the round-off scale on one
    machine, 4e-14 on another), so the equation is checked in the KSP's own norm. Factor 2: the
    KSP tests its recurrence residual, which leaves the true one by round-off (eps |x| cond, here
    ~1e-3 of the bound). The force lam = k (lb - x_c) is computed from x, so it holds to round-off."""
    K, b, cglob, lb = string(400)
    k = 1e3 * np.ones(len(cglob))
    krylov = {}
    x, lam, info, its = solve(K, b, cglob, lb, k, krylov)
    assert info["n_active"] > SCHUR_MAX_ACTIVE
    assert krylov["norm"] == PETSc.KSP.NormType.PRECONDITIONED and krylov["zero_guess"]
    r, force = penalised_residual(K, b, cglob, lb, k, x)
    rhs = b.copy()
    active = force > 0.0
    rhs[cglob[active]] += k[active] * lb[active]
    Kc = K.tocsc()
    r_pre, rhs_pre = (np.linalg.norm(scipy.sparse.linalg.spsolve(Kc, v)) for v in (r, rhs))
    assert r_pre <= 2.0 * krylov["rtol"] * rhs_pre, f"preconditioned residual {r_pre / rhs_pre:.2e} of |K^-1 rhs|"
    scale = (scipy.sparse.linalg.norm(K, np.inf) + np.max(k)) * np.max(np.abs(x))
    assert np.max(np.abs(lam - force)) <= EQ_RTOL * scale
    assert np.max(np.abs(x - dense_reference(K, b, cglob, lb, k))) <= X_RTOL * np.max(np.abs(x))
    assert its > info["its"]                     # CG iterations were counted


def test_stiff_penalty_tends_to_the_obstacle_problem():
    """As k grows, max penetration (lb - x_c)_+ times k tends to the obstacle problem's
    largest multiplier: penetration ~ 1/k."""
    K, b, cglob, lb = string(120, constrained_every=3)
    pen = []
    ks = (1e4, 1e5, 1e6)
    for s in ks:
        x, lam, _, _ = solve(K, b, cglob, lb, s * np.ones(len(cglob)))
        pen.append(np.max(lb - x[cglob]))
    slope = np.polyfit(np.log(ks), np.log(pen), 1)[0]
    assert abs(slope + 1.0) < 0.02, slope


def test_bad_stiffness_refused():
    K, b, cglob, lb = string(20)
    A, bv, xv, c, lbl, kl = distributed(K, b, cglob, lb, np.ones(len(cglob)))
    try:
        with pytest.raises(ValueError, match="finite and > 0"):
            PenaltyNewton(A, c, lbl, 0.0 * kl)
        with pytest.raises(ValueError, match="stiffnesses for"):
            PenaltyNewton(A, c, lbl, kl[:-1] if len(kl) else np.ones(1))
    finally:
        for o in (A, bv, xv):
            o.destroy()


def test_no_convergence_raises():
    """A max_it of 1 cannot find the active set from x = 0: VIError, not a silent result."""
    K, b, cglob, lb = string(60)
    A, bv, xv, c, lbl, kl = distributed(K, b, cglob, lb, 1e3 * np.ones(len(cglob)))
    solver = PenaltyNewton(A, c, lbl, kl, max_it=1)
    try:
        with pytest.raises(VIError, match="did not converge"):
            solver.solve(bv, xv)
    finally:
        solver.destroy()
        for o in (A, bv, xv):
            o.destroy()
