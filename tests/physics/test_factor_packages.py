"""The step solvers use the packages this PETSc has: CHOLMOD where present, else MUMPS, else
PETSc's own factorisation; run.json records which. Strategies needing hypre are refused in one
line where it is absent. The absence is pretended by replacing :func:`sdm_dolfinx.compat.petsc_has`
(the PyPI wheel dolfinx-solver-real has neither SuiteSparse nor hypre)."""
import gc

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli, compat, membrane, simulate
from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.solvers import active_set, factorisation

COMM = MPI.COMM_WORLD

#: the same run through another factorisation: round-off of the Newton systems over 200 steps,
#: the bound test_strategies.py uses between the strategies (same active sets, same iterations)
DIRECT_RTOL = 1e-10


def without(*absent):
    """A :func:`compat.petsc_has` for a PETSc lacking the packages ``absent``."""
    real = compat.petsc_has
    return lambda package: package not in absent and real(package)


def run(**kw):
    """(time series, factor_package) of the membrane P1+/P0, N = 8, 200 steps, contact from step 129."""
    r = simulate(membrane.problem(N=8, comm=COMM), pair="P1+/P0", dt=2e-3, T=0.4, linear="schur", **kw)
    ts = {c: r.timeseries[c].copy() for c in ("energy", "u_probe", "lambda_probe", "n_active", "newton_its")}
    package = r.info["factor_package"]
    del r
    gc.collect()
    COMM.Barrier()
    return ts, package


def assert_same(ts, ref, what):
    for c in ("energy", "u_probe", "lambda_probe"):
        err = np.max(np.abs(ts[c] - ref[c])) / max(np.abs(ref[c]).max(), 1e-300)
        assert err <= DIRECT_RTOL, f"{what}: {c} differs by {err:.2e} (relative)"
    assert np.array_equal(ts["n_active"], ref["n_active"]), what
    assert np.array_equal(ts["newton_its"], ref["newton_its"]), what


@pytest.mark.skipif(not compat.petsc_has("suitesparse"), reason="this PETSc has no SuiteSparse (CHOLMOD)")
def test_fallback_factorisations_agree_with_cholmod(monkeypatch):
    """CHOLMOD where PETSc has it (1 rank, or one copy per rank of this small matrix); without
    SuiteSparse MUMPS, without either PETSc's own Cholesky: the same run to round-off, and
    run.json says which factorised it."""
    ref, package = run()
    assert package == "cholmod"
    assert ref["n_active"].max() > 10
    monkeypatch.setattr(compat, "petsc_has", without("suitesparse"))
    ts, package = run()
    assert package == "mumps"
    assert_same(ts, ref, "MUMPS instead of CHOLMOD")
    monkeypatch.setattr(compat, "petsc_has", without("suitesparse", "mumps"))
    ts, package = run()
    assert package == "petsc"
    assert_same(ts, ref, "PETSc's Cholesky instead of CHOLMOD")


def test_factor_package_choice(monkeypatch):
    """One process: CHOLMOD for SPD, MUMPS otherwise; distributed: MUMPS; a distributed
    factorisation without MUMPS is refused in one line."""
    monkeypatch.setattr(compat, "petsc_has", lambda package: True)
    assert factorisation.factor_package(True, True) == "cholmod"
    assert factorisation.factor_package(True, False) == "mumps"
    assert factorisation.factor_package(False, True) == "mumps"
    monkeypatch.setattr(compat, "petsc_has", lambda package: package == "mumps")
    assert factorisation.factor_package(True, True) == "mumps"
    monkeypatch.setattr(compat, "petsc_has", lambda package: False)
    assert factorisation.factor_package(True, True) == "petsc"
    with pytest.raises(factorisation.FactorPackageError, match="no MUMPS"):
        factorisation.factor_package(False, True)


def test_no_factorisation_records_none():
    """A strategy without a factorisation for the run records factor_package None."""
    r = simulate(membrane.problem(N=4, comm=COMM), pair="P1+/P0", dt=2e-3, T=0.01, linear="cg-gamg")
    assert "factor_package" in r.info and r.info["factor_package"] is None
    del r
    gc.collect()
    COMM.Barrier()


@pytest.mark.parametrize("linear", active_set.HYPRE_STRATEGIES)
def test_hypre_strategies_refused_without_hypre(linear, monkeypatch, mpi_tmp_path, capsys):
    """Without hypre, ``amg`` and ``cg-amg`` are refused in one line (an SdmError; the command
    line's status 2, no traceback, nothing written), and ``auto`` does not choose ``amg``."""
    monkeypatch.setattr(compat, "petsc_has", without("hypre"))
    with pytest.raises(SdmError, match=f"linear {linear} needs hypre's BoomerAMG, and this PETSc has no hypre"):
        simulate(membrane.problem(N=4, comm=COMM), dt=2e-3, T=0.01, linear=linear)
    out = mpi_tmp_path / "never"
    assert cli.main(["membrane", "--N", "4", "--T", "0.01", "--linear", linear, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert f"--linear {linear} needs hypre's BoomerAMG" in err and len(err.strip().splitlines()) == 1, err
        assert "Traceback" not in err
    assert not out.exists()
    assert active_set.choose_strategy(active_set.SCHUR_MAX_CONSTRAINTS + 1, True) == "schur"
    with pytest.raises(SdmError, match="no hypre"):      # the solver itself, for a direct user
        _solver(linear)


def _solver(linear):
    """A SemismoothNewton on a 2x2 identity with strategy ``linear``."""
    from petsc4py import PETSc
    from sdm_dolfinx.solvers import SemismoothNewton
    K = PETSc.Mat().createAIJ(((None, 2 * COMM.size), (None, 2 * COMM.size)), nnz=(1, 0), comm=COMM)
    K.setUp()
    lo, hi = K.getOwnershipRange()
    for i in range(lo, hi):
        K.setValue(i, i, 1.0)
    K.assemble()
    try:
        return SemismoothNewton(K, [0], [0.0], linear=linear)
    finally:
        K.destroy()
