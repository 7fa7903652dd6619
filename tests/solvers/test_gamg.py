"""The iterative strategy ``cg-gamg`` (GAMG with the rigid body modes, one set-up per run) gives
the factorised ``schur``'s steps on the coarse ball, a few steps into contact."""
import gc

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import simulate
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.iterative import rigid_body_modes
from sdm_dolfinx.problems import ball

COMM = MPI.COMM_WORLD

#: CG stops at a relative residual of 1e-12 (in GAMG's norm); K's condition number on the
#: inactive set (~1e4 here) makes the solution agree with the direct one to ~1e-8
GAMG_RTOL = 1e-7


def _run(linear):
    # 0.001 mm above the plane at 100 mm/s: contact from the first step of 4e-5 s
    r = simulate(ball.problem(level=1, height=0.001, comm=COMM), pair="P2/P1", dt=4e-5, T=2.4e-4, linear=linear)
    out = {c: r.timeseries[c].copy() for c in ("energy", "u_probe", "lambda_probe", "n_active")}
    out["U"] = r.U.array.copy()
    out["linear"] = r.info.get("linear_strategy")
    del r
    gc.collect()
    COMM.Barrier()
    return out


@pytest.mark.slow           # 15 s at load 3.5 (6 s of CPU)
@pytest.mark.skipif(COMM.size > 1, reason="3-D runs: serial, as tests/physics/test_ball.py")
def test_cg_gamg_gives_the_factorised_steps():
    ref, it = _run("schur"), _run("cg-gamg")
    assert ref["n_active"].max() > 0                      # in contact
    assert np.array_equal(it["n_active"], ref["n_active"])
    for c in ("energy", "u_probe", "lambda_probe"):
        scale = np.abs(ref[c]).max()
        assert np.abs(it[c] - ref[c]).max() <= GAMG_RTOL * scale, c
    scale = COMM.allreduce(np.abs(ref["U"]).max(), op=MPI.MAX)
    assert COMM.allreduce(np.abs(it["U"] - ref["U"]).max(), op=MPI.MAX) <= GAMG_RTOL * scale


def test_rigid_body_modes_are_in_the_kernel_of_the_stiffness():
    """A (free ball, no Dirichlet dofs) annihilates the 6 modes up to round-off."""
    d = Discretisation(ball.problem(level=1, comm=COMM), "P2/P1")
    ns = rigid_body_modes(d.W)
    vecs = ns.getVecs()
    assert len(vecs) == 6
    y = d.A.createVecLeft()
    norm_A = d.A.norm()
    for v in vecs:
        d.A.mult(v, y)
        assert y.norm() <= 1e-10 * norm_A
    G = np.array([[a.dot(b) for b in vecs] for a in vecs])
    assert np.allclose(G, np.eye(6), atol=1e-12)
