"""The step solvers on hand-made LCPs, without meshes: every strategy meets the KKT conditions.

The LCP of one step (paper, after eq. (14)) is

    x_c >= lb,   lam = (K x - b)_c >= 0,   lam . (x_c - lb) = 0,   (K x - b)_i = 0 off c.

The matrices are a 1-D obstacle problem (a string pulled down onto a parabolic obstacle: a
Laplacian plus a mass-like diagonal, SPD) and a symmetric saddle point [A, B^T; B, -D]
whose first block's Schur complement is SPD (the block formulation of the method). The
reference solution is independent of the solvers: for SPD K the LCP is the bound-constrained
QP min 1/2 x^T K x - b^T x, i.e. the least-squares problem min |R x - R^-T b| with K = R^T R,
solved by scipy's bounded-variable least squares (BVLS, an exact active-set method).
Matrices are distributed over the ranks by rows (run serially and under mpirun -n 2).
"""
import re

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import scipy.optimize
import scipy.sparse

from sdm_dolfinx.solvers import (LINEAR_STRATEGIES, VI_SOLVERS, SemismoothNewton, SnesVI, VIError,
                                 make_vi_solver, registry)
from sdm_dolfinx.solvers.active_set import missing_package
from sdm_dolfinx.solvers.options import options_used

COMM = MPI.COMM_WORLD
#: size of the string problem (rows of K) and of the saddle point's blocks
N = 120
N1, N2 = 80, 40
#: direct strategies solve each Newton system to round-off: cond(K) ~ 5e3 (string), 5e4 (saddle)
#: solution agrees with BVLS's to ~cond eps relative; 1e-10 leaves a margin
DIRECT_RTOL = 1e-10
#: Krylov strategies stop at a KSP relative residual of 1e-12 (SemismoothNewton's default):
#: x is exact to ~1e-12 relative, and the multipliers (K x - b)_A, of size ||K|| |x| ~ 1e4
#: times max|b| here, to ~1e-8 max|b| (measured 3e-9 to 7e-9); vinewtonrsls stops at its
#: SNES tolerance 1e-10 x max|b|
ITERATIVE_RTOL = 1e-7
#: GMRES (symmetric indefinite K) stops on the left-preconditioned residual: the true one is
#: up to ||K|| ~ 6e4 times larger at the x rows (measured 2e-7 max|b|; x itself to 1e-10)
GMRES_RTOL = 1e-6
#: the strategies that solve each Newton system by a Krylov method
KRYLOV = ("cg-factor", "amg", "cg-amg", "cg-gamg", "cg-pmg")


# ------------------------------------------------------------------------------ problems
def local_range(n):
    """The rows [lo, hi) of n that this rank owns (as PETSc's default split)."""
    sizes = [n // COMM.size + (r < n % COMM.size) for r in range(COMM.size)]
    lo = sum(sizes[:COMM.rank])
    return lo, lo + sizes[COMM.rank]


def petsc_aij(K, rows):
    """A PETSc AIJ matrix with this rank's ``rows`` (a range) of the global scipy matrix K."""
    K = scipy.sparse.csr_matrix(K)
    n = K.shape[0]
    sub = K[rows.start:rows.stop]
    csr = (sub.indptr.astype(PETSc.IntType), sub.indices.astype(PETSc.IntType), sub.data)
    A = PETSc.Mat().createAIJ(((len(rows), n), (len(rows), n)), csr=csr, comm=COMM)
    A.assemble()
    return A


def string_problem(n=N):
    """The string over a parabolic obstacle: K = h^-2 tridiag(-1, 2, -1) + I, load -10,
    every dof but one in three constrained (so both kinds of rows are tested)."""
    h = 1.0 / (n + 1)
    s = np.linspace(h, 1.0 - h, n)
    K = scipy.sparse.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]) / h ** 2
    K = K + scipy.sparse.identity(n)
    b = -10.0 * np.ones(n)
    cglob = np.flatnonzero(np.arange(n) % 3 != 1)
    lb = -0.3 + 0.2 * (s[cglob] - 0.5) ** 2
    return K.tocsr(), b, cglob, lb, np.arange(n)


def saddle_problem(n1=N1, n2=N2):
    """[A, B^T; B, -D] (x: a string with A as above, y: averages of pairs of x), constraints
    on x. The global order puts each rank's x rows, then its y rows, in its range of rows (as
    dolfinx's block matrices do); ``perm[i]`` is the global row of natural unknown i
    (x first, then y)."""
    A, b1, cglob, lb, _ = string_problem(n1)
    B = scipy.sparse.lil_matrix((n2, n1))
    for j in range(n2):
        B[j, 2 * j] = B[j, 2 * j + 1] = 1.0
    D = scipy.sparse.diags(1.0 + 0.5 * np.cos(np.arange(n2)))
    Kn = scipy.sparse.bmat([[A, B.T], [B, -D]]).tocsr()
    bn = np.concatenate([b1, 0.3 * np.ones(n2)])
    sizes1 = [n1 // COMM.size + (r < n1 % COMM.size) for r in range(COMM.size)]
    sizes2 = [n2 // COMM.size + (r < n2 % COMM.size) for r in range(COMM.size)]
    perm, start = np.empty(n1 + n2, dtype=int), 0
    for r in range(COMM.size):
        x0, y0 = sum(sizes1[:r]), sum(sizes2[:r])
        perm[x0:x0 + sizes1[r]] = start + np.arange(sizes1[r])
        perm[n1 + y0:n1 + y0 + sizes2[r]] = start + sizes1[r] + np.arange(sizes2[r])
        start += sizes1[r] + sizes2[r]
    P = scipy.sparse.csr_matrix((np.ones(n1 + n2), (perm, np.arange(n1 + n2))))
    K = (P @ Kn @ P.T).tocsr()
    b = P @ bn
    return K, b, perm[cglob], lb, perm, (A, B, D, b1, bn[n1:])


def reference(K, b, cglob, lb):
    """The LCP's solution by BVLS on the equivalent least-squares problem (K SPD)."""
    L = np.linalg.cholesky(K.toarray())
    d = np.linalg.solve(L, b)               # R = L^T, R^T d = b
    lo = np.full(len(b), -np.inf)
    lo[cglob] = lb
    res = scipy.optimize.lsq_linear(L.T, d, bounds=(lo, np.inf), method="bvls", tol=1e-14)
    assert res.success
    return res.x


def saddle_reference(parts, cglob_x, lb):
    """The saddle point's LCP through its Schur complement S = A + B^T D^-1 B on x."""
    A, B, D, b1, b2 = parts
    Dinv = scipy.sparse.diags(1.0 / D.diagonal())
    S = (A + B.T @ Dinv @ B).tocsr()
    x = reference(S, b1 + B.T @ (Dinv @ b2), cglob_x, lb)
    return np.concatenate([x, Dinv @ (B @ x - b2)])


class Distributed:
    """The PETSc data of one LCP on this rank: K, b, x and the owned constrained dofs."""

    def __init__(self, K, b, cglob, lb):
        rows = range(*local_range(K.shape[0]))
        self.K = petsc_aij(K, rows)
        self.b, self.x = self.K.createVecLeft(), self.K.createVecRight()
        self.b.array[:] = b[rows.start:rows.stop]
        own = (cglob >= rows.start) & (cglob < rows.stop)
        self.cdofs = (cglob[own] - rows.start).astype(np.int32)
        self.lb = lb[own]
        self.rows = rows

    def gather(self, v):
        return np.concatenate(COMM.allgather(v.array.copy()))

    def destroy(self):
        for o in (self.K, self.b, self.x):
            o.destroy()


def assert_kkt(Kg, bg, cglob, lb, x, rtol):
    """The KKT conditions on the global arrays, relative to max|b| (forces) and max|lb|
    (displacements)."""
    fscale, xscale = np.max(np.abs(bg)), max(np.max(np.abs(lb)), 1e-300)
    r = Kg @ x - bg
    lam, gap = r[cglob], x[cglob] - lb
    free = np.setdiff1d(np.arange(len(bg)), cglob)
    assert np.min(gap) >= -rtol * xscale, f"bound violated by {-np.min(gap):.2e}"
    assert np.min(lam) >= -rtol * fscale, f"negative multiplier {np.min(lam):.2e}"
    compl = np.minimum(lam / fscale, gap / xscale)          # zero where the pair is complementary
    assert np.max(np.abs(compl)) <= rtol, f"complementarity off by {np.max(np.abs(compl)):.2e}"
    assert np.max(np.abs(r[free]), initial=0.0) <= rtol * fscale, "equation off the constraints"


# ------------------------------------------------------------------------------ fixtures
@pytest.fixture
def string():
    K, b, cglob, lb, _ = string_problem()
    d = Distributed(K, b, cglob, lb)
    xref = reference(K, b, cglob, lb)
    n_act = np.count_nonzero(xref[cglob] - lb <= 1e-12)
    assert 5 <= n_act < len(cglob)             # some bounds active, not all
    yield d, (K, b, cglob, lb, xref)
    d.destroy()


@pytest.fixture
def clean_options():
    """The global options database is the same after the test as before it."""
    before = PETSc.Options().getAll()
    yield
    after = PETSc.Options().getAll()
    assert after == before, f"options left behind: {set(after) ^ set(before)}"


def solve_and_check(solver, d, problem, rtol):
    K, b, cglob, lb, xref = problem
    d.x.set(0.0)
    info = solver.solve(d.b, d.x)
    x = d.gather(d.x)
    assert_kkt(K, b, cglob, lb, x, rtol)
    assert np.max(np.abs(x - xref)) <= rtol * np.max(np.abs(xref))
    n_ref = int(np.count_nonzero(xref[cglob] - lb <= rtol * np.max(np.abs(lb))))
    assert info["n_active"] == n_ref and info["its"] >= 1
    # the solver's multipliers are K x - b at the active constraints, 0 elsewhere
    lam = np.concatenate(COMM.allgather(np.asarray(solver.lam)))
    r = (K @ x - b)[cglob]
    assert np.max(np.abs(lam - np.where(lam != 0.0, r, 0.0))) <= rtol * np.max(np.abs(b))
    return info


# ------------------------------------------------------------------------------ tests
@pytest.mark.parametrize("linear", [pytest.param(s, marks=pytest.mark.skipif(
    bool(missing_package(s)), reason=f"this PETSc lacks what {s} needs (hypre)")) for s in LINEAR_STRATEGIES
    if s != "cg-pmg"])      # it coarsens a discretisation's P2 (tests/solvers/test_pmg.py)
def test_semismooth_newton_every_strategy(string, linear, clean_options):
    """Each linear strategy of the semi-smooth Newton solves the string's LCP (SPD)."""
    d, problem = string
    solver = make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear=linear)
    rtol = ITERATIVE_RTOL if linear in KRYLOV else DIRECT_RTOL
    info = solve_and_check(solver, d, problem, rtol)
    assert info["its"] <= 50
    assert solver.total_linear_its >= info["its"]
    # a second step from the converged state and active set: one iteration
    assert solver.solve(d.b, d.x)["its"] == 1
    solver.destroy()


def test_cg_pmg_on_a_bare_matrix_is_refused_in_one_line(string, clean_options):
    """cg-pmg coarsens the P2 of a run's discretisation: a matrix without its interpolation is refused."""
    d, _ = string
    with pytest.raises(VIError) as e:
        make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear="cg-pmg")
    assert "\n" not in str(e.value) and "choose cg-gamg" in str(e.value)


@pytest.mark.parametrize("snes_type", ["vinewtonrsls", "vinewtonssls"])
def test_snes_vi(string, snes_type, clean_options):
    """PETSc's vinewtonrsls and vinewtonssls solve the same LCP (to their SNES tolerance) and
    leave the step matrix K as it was (vinewtonssls writes its semi-smooth Jacobian into the
    Jacobian matrix it is given: SnesVI gives it its own)."""
    d, problem = string
    K0 = d.K.copy()
    solver = make_vi_solver(snes_type, d.K, d.cdofs, d.lb)
    assert isinstance(solver, SnesVI) and solver.snes.getType() == snes_type
    solve_and_check(solver, d, problem, ITERATIVE_RTOL)
    K0.axpy(-1.0, d.K)
    assert K0.norm() == 0.0
    # a second step from the solution: converged at once (rsls) or in a few iterations (ssls)
    assert solver.solve(d.b, d.x)["its"] <= 3
    solver.destroy()
    K0.destroy()


@pytest.mark.parametrize("snes_type", ["vinewtonrsls", "vinewtonssls"])
def test_snes_max_it_below_one_is_refused(string, snes_type, clean_options):
    """-sdm_snes_max_it 0 or -5 is refused when the solver is made, not at the first step."""
    d, _ = string
    for value in ("0", "-5"):
        with pytest.raises(VIError, match=r"snes_max_it.*is not an integer >= 1"):
            make_vi_solver(snes_type, d.K, d.cdofs, d.lb, options={"snes_max_it": value})


@pytest.mark.parametrize("linear", ["schur", "cg-factor", "lu"])
def test_saddle_point(linear, clean_options):
    """The symmetric indefinite block system (GMRES, LU / LDL^T): the strategies that do not
    need an SPD K (AMG ones do)."""
    K, b, cglob, lb, perm, parts = saddle_problem()
    d = Distributed(K, b, cglob, lb)
    solver = SemismoothNewton(d.K, d.cdofs, d.lb, symmetric_positive=False, linear=linear)
    info = solver.solve(d.b, d.x)
    x = d.gather(d.x)
    rtol = GMRES_RTOL if linear in KRYLOV else DIRECT_RTOL
    assert_kkt(K, b, cglob, lb, x, rtol)
    xref = saddle_reference(parts, np.argsort(perm)[cglob], lb)[np.argsort(perm)]
    assert np.max(np.abs(x - xref)) <= rtol * np.max(np.abs(xref))
    assert info["n_active"] >= 3
    solver.destroy()
    d.destroy()


def test_too_few_iterations_raise(string, clean_options):
    """One Newton iteration from x = 0 cannot find the active set: VIError says so, for the
    argument, the ``options`` dict and SNES VI alike."""
    d, _ = string
    solver = SemismoothNewton(d.K, d.cdofs, d.lb, linear="schur", max_it=1)
    with pytest.raises(VIError, match="semi-smooth Newton did not converge in 1 iterations"):
        solver.solve(d.b, d.x)
    solver.destroy()
    solver = make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear="lu", options={"vi_max_it": "1"})
    d.x.set(0.0)
    with pytest.raises(VIError, match=r"did not converge in 1 iterations \(\d+ constraints still infeasible\)"):
        solver.solve(d.b, d.x)
    solver.destroy()
    solver = make_vi_solver("vinewtonrsls", d.K, d.cdofs, d.lb, options={"snes_max_it": "1"})
    d.x.set(0.0)
    with pytest.raises(VIError, match=r"SNES vinewtonrsls diverged \(reason -5: DIVERGED_MAX_IT\)"):
        solver.solve(d.b, d.x)
    solver.destroy()


def test_invalid_vi_option_names_its_source(string, clean_options):
    """A bad -..._vi_rtol is refused, naming the option as it was given."""
    d, _ = string
    with pytest.raises(VIError, match=r"-sdm_\d+_vi_rtol: 2\.0 is not a number in \(0, 1\)"):
        make_vi_solver("ssn", d.K, d.cdofs, d.lb, options={"vi_rtol": "2"})
    opts = PETSc.Options()
    opts["sdm_vi_rtol"] = "2"
    try:
        with pytest.raises(VIError, match=r"^-sdm_vi_rtol: 2\.0 is not"):
            make_vi_solver("vinewtonrsls", d.K, d.cdofs, d.lb)
    finally:
        opts.delValue("sdm_vi_rtol")


def test_instances_have_their_own_options(string, clean_options):
    """Two solvers with different ``options`` do not see each other's, and nothing of
    either is left in the global options database (``clean_options``)."""
    d, problem = string
    a = make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear="cg-factor",
                       options={"vi_max_it": "70", "ksp_type": "gmres", "ksp_rtol": "1e-13"})
    b = make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear="cg-factor")
    assert re.fullmatch(r"sdm_\d+_", a.prefix) and re.fullmatch(r"sdm_\d+_", b.prefix) and a.prefix != b.prefix
    assert a.snes.getOptionsPrefix() == a.prefix and a.inactive.ksp.getOptionsPrefix() == a.prefix
    assert (a.max_it, b.max_it) == (70, 500)
    assert a.inactive.ksp.getType() == "gmres" and b.inactive.ksp.getType() == "cg"
    assert a.inactive.ksp.getTolerances()[0] == 1e-13 and b.inactive.ksp.getTolerances()[0] == 1e-12
    for s in (a, b):
        solve_and_check(s, d, problem, ITERATIVE_RTOL)
        assert not [k for k in PETSc.Options().getAll() if k.startswith(s.prefix)]
        s.destroy()
    c = make_vi_solver("vinewtonrsls", d.K, d.cdofs, d.lb, prefix="unit_given_")
    assert c.prefix == "unit_given_" == c.snes.getOptionsPrefix()
    c.destroy()


def test_shared_options_reach_every_instance(string, clean_options):
    """A shared ``sdm_`` option of the database (the command line's -sdm_...) applies to
    every instance; the instance's own ``-<prefix>...`` wins over it, and it wins over the
    ``options`` dict. PETSc counts it as used (``-options_left`` stays quiet) unless nothing
    read it (a misspelt one)."""
    d, problem = string
    opts = PETSc.Options()
    opts["sdm_vi_max_it"] = "40"
    opts["sdm_ksp_type"] = "gmres"
    opts["sdm_vi_max_itt"] = "41"          # misspelt
    opts["unit_own_vi_max_it"] = "45"
    try:
        s1 = make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear="cg-factor")
        s2 = make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear="cg-factor", options={"vi_max_it": "60"})
        s3 = make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear="cg-factor", prefix="unit_own_")
        assert (s1.max_it, s2.max_it, s3.max_it) == (40, 40, 45)
        assert s1.inactive.ksp.getType() == s3.inactive.ksp.getType() == "gmres"
        solve_and_check(s1, d, problem, ITERATIVE_RTOL)
        assert options_used("sdm_vi_max_it") and options_used("sdm_ksp_type")
        assert not options_used("sdm_vi_max_itt")
        for s in (s1, s2, s3):
            s.destroy()
    finally:
        for k in ("sdm_vi_max_it", "sdm_ksp_type", "sdm_vi_max_itt", "unit_own_vi_max_it"):
            opts.delValue(k)


def test_shared_options_at_solve_time(string, capfd, clean_options):
    """Options read at each solve (here -sdm_snes_converged_reason) reach the instance."""
    d, problem = string
    opts = PETSc.Options()
    opts["sdm_snes_converged_reason"] = ""
    try:
        s = make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear="schur")
        solve_and_check(s, d, problem, DIRECT_RTOL)
        s.destroy()
    finally:
        opts.delValue("sdm_snes_converged_reason")
    out = capfd.readouterr().out
    if COMM.rank == 0:
        assert f"Nonlinear {s.prefix} solve converged due to CONVERGED_FNORM_ABS" in out


def test_prefix_same_on_every_rank_after_a_local_solver(clean_options):
    """A solver made on rank 0 only (COMM_SELF) does not make the next collective solver's
    prefix differ between ranks."""
    if COMM.rank == 0:
        K = petsc_aij_self(4)
        s = SemismoothNewton(K, np.arange(4, dtype=np.int32), -np.ones(4), linear="lu")
        s.destroy()
        K.destroy()
    K, b, cglob, lb, _ = string_problem(12)
    d = Distributed(K, b, cglob, lb)
    s = make_vi_solver("ssn", d.K, d.cdofs, d.lb)
    assert len(set(COMM.allgather(s.prefix))) == 1
    s.destroy()
    d.destroy()


def petsc_aij_self(n):
    """2 I on COMM_SELF."""
    A = PETSc.Mat().createAIJ((n, n), nnz=1, comm=PETSc.COMM_SELF)
    for i in range(n):
        A.setValue(i, i, 2.0)
    A.assemble()
    return A


def test_registry(string, monkeypatch, clean_options):
    """VI_SOLVERS lists the registered names (a tuple for argparse); a new solver is one
    register() call; unknown names are refused with the list."""
    assert tuple(VI_SOLVERS) == ("ssn", "vinewtonrsls", "vinewtonssls") == VI_SOLVERS
    assert "ssn" in VI_SOLVERS and ", ".join(VI_SOLVERS) == "ssn, vinewtonrsls, vinewtonssls"
    monkeypatch.setattr(registry, "_FACTORIES", dict(registry._FACTORIES))
    made = []

    def factory(K, cdofs, lb, **kw):
        made.append(kw["prefix"])
        return "solver"
    registry.register("mine", factory)
    assert VI_SOLVERS[-1] == "mine" and len(VI_SOLVERS) == 4
    d, _ = string
    assert make_vi_solver("mine", d.K, d.cdofs, d.lb, prefix="p_") == "solver" and made == ["p_"]
    with pytest.raises(ValueError, match="registered already"):
        registry.register("ssn", factory)
    with pytest.raises(ValueError, match=r"unknown VI solver 'nope'; choose one of ssn, .*, mine"):
        make_vi_solver("nope", d.K, d.cdofs, d.lb)
    with pytest.raises(ValueError, match="unknown linear strategy"):
        make_vi_solver("ssn", d.K, d.cdofs, d.lb, linear="nope")


def test_murty_rule_exchanges_one_condition_after_its_patience():
    """solvers.base.MurtyRule (the three active-set loops' cycle breaker): no single exchange
    while the violated count falls or for PATIENCE iterations without a decrease; then the mask
    of exactly one violated condition over all ranks, the one of largest global index."""
    from sdm_dolfinx.solvers.base import MurtyRule
    comm = MPI.COMM_WORLD
    n = 5
    gidx = comm.rank * n + np.arange(n)                      # rank-contiguous global indices
    bad = np.zeros(n, dtype=bool)
    bad[[0, 2]] = True                                       # on every rank; the largest is the last rank's 2
    rule = MurtyRule(gidx, comm)
    for count in (9, 7, 4):                                  # falling: never
        assert rule.single(count, bad) is None
    for _ in range(MurtyRule.PATIENCE):                      # not falling: patience
        assert rule.single(4, bad) is None
    one = rule.single(4, bad)
    assert comm.allreduce(int(one.sum()), op=MPI.SUM) == 1
    assert one[2] == (comm.rank == comm.size - 1) and bad[one].all()
    assert rule.single(5, bad) is not None                  # still no decrease: single exchanges go on
    assert rule.single(3, bad) is None                      # a decrease: full updates again
