"""Every linear strategy of the semi-smooth Newton gives the same runs (membrane, consistent block, disc)."""
import gc

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest

from sdm_dolfinx import compat, disc, membrane, simulate
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.solvers import VIError, active_set, augmented, factorisation, schur

COMM = MPI.COMM_WORLD
#: this PETSc has hypre (the amg strategies; the PyPI wheel has none)
HYPRE = compat.petsc_has("hypre")
COLUMNS = ("energy", "u_probe", "lambda_probe", "n_active", "newton_its")


#: direct solves: round-off of the Newton systems, accumulated over 200 steps
DIRECT_RTOL = 1e-10


#: KSP rtol 1e-12 times the condition number of the reduced systems (~1e4)
AMG_RTOL = 5e-8


def series(problem, **kw):
    """The time series of one run (no PETSc object kept: destructors are collective)."""
    r = simulate(problem(), **kw)
    ts = {c: r.timeseries[c].copy() for c in COLUMNS}
    ts["linear"] = r.info["linear_its_total"]
    del r
    gc.collect()
    COMM.Barrier()
    return ts


def assert_same(ts, ref, rtol, what):
    for c in ("energy", "u_probe", "lambda_probe"):
        scale = max(np.abs(ref[c]).max(), 1e-300)
        err = np.max(np.abs(ts[c] - ref[c])) / scale
        assert err <= rtol, f"{what}: {c} differs by {err:.2e} (relative)"
    if rtol <= DIRECT_RTOL:       # same active sets, same Newton iterations
        assert np.array_equal(ts["n_active"], ref["n_active"]), what
        assert np.array_equal(ts["newton_its"], ref["newton_its"]), what


def membrane8():
    return membrane.problem(N=8, comm=COMM)


def disc1():
    return disc.problem(level=1, comm=COMM)


@pytest.fixture
def small_schur(monkeypatch):
    """``schur`` with at most 5 active constraints per dense system: larger active sets go
    through its CG fallback (preconditioned by the same factorisation)."""
    monkeypatch.setattr(schur, "SCHUR_MAX_ACTIVE", 5)
    monkeypatch.setattr(schur, "SCHUR_COST_MODEL", False)    # 5, not a threshold measured above it


@pytest.mark.slow
def test_membrane_strategies_agree():
    """P1+/P0, N = 8, 200 steps with contact from step 129 (up to 27 vertices in contact)."""
    kw = dict(pair="P1+/P0", dt=2e-3, T=0.4)
    ref = series(membrane8, linear="lu", **kw)
    assert ref["n_active"].max() > 10
    for lin in ("schur", "cg-factor", "auto"):
        assert_same(series(membrane8, linear=lin, **kw), ref, DIRECT_RTOL, lin)
    for lin in ("amg", "cg-amg") if HYPRE else ():      # refused without hypre (test_factor_packages.py)
        assert_same(series(membrane8, linear=lin, **kw), ref, AMG_RTOL, lin)
    assert_same(series(membrane8, vi_solver="vinewtonrsls", **kw), ref, 1e-8, "vinewtonrsls")


@pytest.mark.slow
def test_schur_krylov_fallback_agrees(small_schur):
    """Newton systems with more than SCHUR_MAX_ACTIVE active constraints use CG."""
    kw = dict(pair="P1+/P0", dt=2e-3, T=0.4)
    ref = series(membrane8, linear="lu", **kw)
    ts = series(membrane8, linear="schur", **kw)
    assert_same(ts, ref, DIRECT_RTOL, "schur with CG fallback")


@pytest.mark.slow
def test_consistent_block_strategies_agree():
    """The (U, V) block system (symmetric indefinite): LU-based Schur and GMRES variants."""
    kw = dict(pair="P2/P1", dt=2e-3, T=0.4, mass="consistent")
    ref = series(membrane8, linear="lu", **kw)
    for lin in ("schur", "cg-factor", "auto"):
        assert_same(series(membrane8, linear=lin, **kw), ref, DIRECT_RTOL, lin)


@pytest.mark.slow
def test_augmented_route_agrees(monkeypatch):
    """P2/P1 through the augmented factorisation (used from 20k dofs) gives K's solution."""
    kw = dict(pair="P2/P1", dt=2e-4, T=0.02)
    ref = series(disc1, linear="lu", **kw)
    monkeypatch.setattr(augmented, "AUG_MIN_ROWS", 0)
    for lin in ("schur", "cg-factor"):
        assert_same(series(disc1, linear=lin, **kw), ref, DIRECT_RTOL, lin + " (augmented)")


def test_disc_strategies_agree():
    """P2/P1 disc, level 1 (618 dofs), dt = 2e-4, the whole bounce (contact from step 48)."""
    kw = dict(pair="P2/P1", dt=2e-4, T=0.02)
    ref = series(disc1, linear="lu", **kw)
    assert ref["n_active"].max() >= 3
    for lin in ("schur", "cg-factor", "auto"):
        assert_same(series(disc1, linear=lin, **kw), ref, DIRECT_RTOL, lin)
    if HYPRE:
        assert_same(series(disc1, linear="cg-amg", **kw), ref, AMG_RTOL, "cg-amg")


def test_augmented_factorisation_solves_K(monkeypatch):
    """For P2/P1 the factorised matrix is [A, a B^T; a B, -D], whose Schur complement is the
    step matrix K = a^2 B^T D^-1 B + A: a solve through it solves K x = r to round-off."""
    monkeypatch.setattr(augmented, "AUG_MIN_ROWS", 0)        # the route is taken from 20k rows
    d = Discretisation(membrane.problem(N=6, comm=COMM), "P2/P1")
    integ = Integrator(d, "midpoint", 1e-2, linear="schur")
    assert integ.factor_matrix is not None            # P2/P1: M is much denser than A
    fac = integ.solver.fac
    r = integ.K.createVecLeft()
    r.setRandom()
    x = integ.K.createVecRight()
    fac.solve(r, x)
    res = integ.K.createVecLeft()
    integ.K.mult(x, res)
    res.axpy(-1.0, r)
    assert res.norm() <= 1e-10 * r.norm()
    # the cached columns are columns of K^-1 too
    g = integ.K.getOwnershipRange()[0] + d.cdofs[:1]
    gids = np.concatenate(COMM.allgather(g))[:2]
    cols = fac.solve_columns(gids.tolist())
    e = integ.K.createVecRight()
    for j, gid in enumerate(gids):
        e.set(0.0)
        lo, hi = integ.K.getOwnershipRange()
        if lo <= gid < hi:
            e.array[gid - lo] = 1.0
        z = e.duplicate()
        z.array[:] = cols[:, j]
        integ.K.mult(z, res)
        res.axpy(-1.0, e)
        assert res.norm() <= 1e-10
    for v in (r, x, res, e, z):
        v.destroy()
    integ.destroy()
    # P1+/P0 (C diagonal, M as sparse as A): K itself is factorised
    d2 = Discretisation(membrane.problem(N=6, comm=COMM), "P1+/P0")
    integ2 = Integrator(d2, "midpoint", 1e-2, linear="schur")
    assert integ2.factor_matrix is None
    integ2.destroy()


def test_auto_choice():
    """``auto``: the Schur strategy unless there are many constraints (then CG + AMG, where PETSc has hypre)."""
    assert active_set.choose_strategy(200, True) == "schur"
    assert active_set.choose_strategy(active_set.SCHUR_MAX_CONSTRAINTS + 1, True) == ("amg" if HYPRE else "schur")
    assert active_set.choose_strategy(active_set.SCHUR_MAX_CONSTRAINTS + 1, False) == "schur"
    with pytest.raises(ValueError, match="unknown linear strategy"):
        simulate(membrane8(), linear="nope", T=0.01)


def test_failed_factorisation_is_reported():
    """A factorisation that fails (here: a singular matrix) raises VIError naming MUMPS's
    error code, on every rank, instead of returning NaNs."""
    n = 4
    A = PETSc.Mat().createAIJ(((n, None), (n, None)), nnz=(1, 0), comm=COMM)
    A.setUp()
    lo, hi = A.getOwnershipRange()
    for i in range(lo, hi):
        A.setValue(i, i, 0.0 if i == lo else 1.0)
    A.assemble()
    with pytest.raises(VIError, match=r"MUMPS INFOG\(1\) = -10"):
        factorisation.factorise(A, COMM, "sdm_test_singular_", kind="lu", package="mumps")
    A.destroy()


@pytest.fixture
def distributed_factor():
    """Factorise with MUMPS distributed over the ranks instead of one copy per rank."""
    opts = PETSc.Options()
    opts["sdm_factor_redundant"] = 0
    yield
    opts.delValue("sdm_factor_redundant")


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="compares a 2-rank run with a serial one: needs mpirun -n 2")
def test_schur_two_ranks_equal_serial():
    """The distributed Schur strategy (columns solved collectively, the dense system
    gathered on every rank) gives the serial time series to round-off."""
    kw = dict(pair="P2/P1", dt=2e-4, T=0.02, linear="schur")
    par = series(disc1, **kw)
    ser = None
    if COMM.rank == 0:
        r = simulate(disc.problem(level=1, comm=MPI.COMM_SELF), **kw)
        ser = {c: r.timeseries[c].copy() for c in COLUMNS}
        del r
        gc.collect()
    ser = COMM.bcast(ser, root=0)
    assert_same(par, ser, DIRECT_RTOL, "2 ranks vs 1")


@pytest.mark.mpi
def test_distributed_factorisation_agrees(distributed_factor):
    """The factorisation distributed over the ranks (MUMPS; the default from
    factorisation.REDUNDANT_MAX_ROWS rows) gives the time series of the redundant one. On dolfinx 0.9 /
    PETSc 3.22 with 2 ranks this factorisation failed in about 1 run in 3 with MUMPS's
    default work-space margin (INFOG(1) = -9; CI, 2026-11): factorisation.factorise now starts from a
    larger margin and retries with a doubled one."""
    kw = dict(pair="P2/P1", scheme="backward-euler", dt=5e-3, T=0.2)
    ref = series(lambda: membrane.problem(N=10, comm=COMM), linear="lu", **kw)
    for lin in ("schur", "cg-factor"):
        assert_same(series(lambda: membrane.problem(N=10, comm=COMM), linear=lin, **kw), ref, DIRECT_RTOL,
                    lin + " (distributed factorisation)")

