"""The matrix-free step operator (sdm_dolfinx/method/matrix_free.py): with ``cg-pmg`` or ``cg-gamg`` on a
frictionless vertex-bound run, K = c_M B^T D^-1 B + c_A A is never assembled and M never formed.

Checked against the assembled matrices of the same discretisation, entry by entry through products:
K x, diag(K) and the coarse operator I^T K I (formed from A and B I) equal the assembled K's, its Dirichlet
rows included, to round-off (1e-12 of their scale); a run's steps equal the factorised ``schur``'s as in
tests/solvers/test_pmg.py, and the run never formed M (run.json says ``step_matrix: matrix-free``).
"""
import json

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import compat, simulate
from sdm_dolfinx.method import iterative, matrix_free, step_matrix
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.problems import ball, membrane

COMM = MPI.COMM_WORLD


@pytest.mark.mpi
@pytest.mark.parametrize("name", ["membrane", "ball"])
def test_the_operator_is_the_assembled_step_matrix(name):
    # the membrane (scalar P2/P1) has Dirichlet dofs on its whole boundary; the ball (3-D vector) none
    problem = membrane.problem(COMM, N=6) if name == "membrane" else ball.problem(COMM, level=1)
    d = Discretisation(problem, "P2/P1")
    assert not d.mass_formed
    c_M, c_A = 4.0 / 1e-3 ** 2, 1.0
    K_free = matrix_free.operator(d, c_M, c_A)
    assert not d.mass_formed                # the operator and its diagonal never form M
    diag_free = K_free.getDiagonal()
    K, _, _ = step_matrix.eliminate(step_matrix.combination(d, c_M, c_A), d)       # forms M
    if name == "membrane":
        assert COMM.allreduce(len(d.ddofs), op=MPI.SUM) > 0
    _same_products(K, K_free, seed=5)
    diag = K.getDiagonal()
    diag.axpy(-1.0, diag_free)
    assert diag.norm(3) <= 1e-12 * K.getDiagonal().norm(3)
    # the coarse operator of cg-pmg from A and B I against the assembled K's Galerkin product
    interpolation = compat.interpolation_matrix(d.P1, d.W)
    coarse, galerkin = iterative.coarse_operator(d, interpolation, c_M, c_A), K.PtAP(interpolation)
    _same_products(galerkin, coarse, seed=6)


def _same_products(reference, other, seed):
    """``other`` x equals ``reference`` x to 1e-12 of its norm (x random, the same on any number of ranks)."""
    x, y, z = reference.createVecRight(), reference.createVecLeft(), reference.createVecLeft()
    lo, hi = reference.getOwnershipRange()
    x.array[:] = np.random.default_rng(seed).standard_normal(reference.getSize()[0])[lo:hi]
    reference.mult(x, y)
    other.mult(x, z)
    z.axpy(-1.0, y)
    assert z.norm(3) <= 1e-12 * y.norm(3)


@pytest.mark.mpi
def test_a_multigrid_run_is_matrix_free_and_never_forms_the_mass(mpi_tmp_path):
    out = mpi_tmp_path / "run"
    r = simulate(ball.problem(COMM, level=1, height=0.001), pair="P2/P1", dt=4e-5, T=1.2e-4, linear="cg-pmg",
                 out=str(out))
    assert json.loads((out / "run.json").read_text())["step_matrix"] == "matrix-free"
    assert r.info["step_matrix"] == "matrix-free"
    assert r.timeseries["n_active"].max() > 0
    assert not r.discretisation.mass_formed


@pytest.mark.parametrize("linear", ["schur", "cg-factor"])
def test_a_factorised_run_assembles_its_step_matrix(linear):
    r = simulate(ball.problem(COMM, level=1, height=0.001), pair="P2/P1", dt=4e-5, T=8e-5, linear=linear)
    assert r.info["step_matrix"] == "assembled"
