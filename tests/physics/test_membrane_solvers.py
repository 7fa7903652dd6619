"""The step solvers on the membrane: they agree, they fail with the step's name, the semi-smooth Newton is a PETSc SNES."""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import StepError, compat, membrane, simulate

COMM = MPI.COMM_WORLD


@pytest.mark.slow
def test_vi_solvers_agree():
    """The semi-smooth Newton (with each linear strategy) and SNES vinewtonrsls solve the
    same LCP: same time series to 1e-8 relative (solver tolerances 1e-10..1e-12)."""
    ref = simulate(membrane.problem(N=8), pair="P1+/P0", dt=2e-3, T=0.4).timeseries
    amg = ({"linear": "amg"},) if compat.petsc_has("hypre") else ()     # refused without hypre
    for kw in ({"linear": "lu"}, *amg, {"vi_solver": "vinewtonrsls"}):
        ts = simulate(membrane.problem(N=8), pair="P1+/P0", dt=2e-3, T=0.4, **kw).timeseries
        for c in ("energy", "u_probe"):
            assert np.allclose(ts[c], ref[c], rtol=1e-8, atol=1e-8 * np.abs(ref[c]).max()), (kw, c)


def test_solver_failure_names_step_and_time(mpi_tmp_path):
    """An injected failure (one Newton iteration allowed: -sdm_vi_max_it 1) raises with step,
    time and reason, and the outputs up to the last good step stay readable."""
    import json
    with pytest.raises(StepError, match=r"step \d+ \(t = [0-9.e-]+\): semi-smooth Newton did not converge "
                                        r"in 1 iterations \(\d+ constraints still infeasible\)"):
        simulate(membrane.problem(N=8), pair="P1+/P0", dt=1e-2, T=0.5, out=mpi_tmp_path,
                 petsc_options={"vi_max_it": "1"})
    if COMM.rank == 0:
        info = json.loads((mpi_tmp_path / "run.json").read_text())
        assert info["status"] == "failed" and "step" in info["error"]
        rows = (mpi_tmp_path / "timeseries.csv").read_text().splitlines()
        assert len(rows) >= 2 and all(len(r.split(",")) == 10 for r in rows)


def test_vinewtonrsls_cycles_on_p2p1_where_the_semismooth_newton_converges():
    """The case that motivated the default solver (STYLE.md): P2/P1, N = 10,
    dt = 1e-3, at the first impact (t ~ 0.25, a whole square of vertices touches at once)
    SNES vinewtonrsls cycles between two active sets until its iteration limit; the
    semi-smooth Newton solves every step of the same run in at most 3 iterations."""
    kw = dict(pair="P2/P1", mass="lumped", dt=1e-3, T=0.3)
    with pytest.raises(StepError, match=r"step 2[0-9]{2} \(t = 0\.2[0-9]*\): SNES vinewtonrsls diverged"):
        simulate(membrane.problem(N=10), vi_solver="vinewtonrsls", **kw)
    ts = simulate(membrane.problem(N=10), **kw).timeseries
    assert ts["n_active"].max() > 0 and ts["newton_its"].max() <= 3


def test_semismooth_newton_is_a_petsc_snes(capfd):
    """The default step solver is a PETSc SNES (type python, prefix sdm_): -sdm_snes_monitor
    prints the Alart-Curnier residual at each iteration, zero (to the tolerance) at the last
    one of every step; -sdm_snes_converged_reason one line per step; -sdm_snes_max_it limits
    the iterations like -sdm_vi_max_it."""
    from petsc4py import PETSc
    opts = PETSc.Options()
    opts["sdm_snes_converged_reason"] = ""      # read at each solve: as from the command line
    try:
        ts = simulate(membrane.problem(N=6), pair="P1+/P0", dt=1e-2, T=0.3,
                      petsc_options={"snes_monitor": ""}).timeseries
    finally:
        opts.delValue("sdm_snes_converged_reason")
    out = capfd.readouterr().out.splitlines()
    norms = [float(ln.split()[-1]) for ln in out if "SNES Function norm" in ln]
    reasons = [ln for ln in out if "solve converged due to CONVERGED_FNORM_ABS" in ln]
    if COMM.rank == 0:
        its = ts["newton_its"][1:].astype(int)
        assert len(norms) == its.sum() and len(reasons) == len(its) == 30
        last = np.cumsum(its) - 1
        assert np.all(np.array(norms)[last] == 0.0)           # no infeasible bound left
        assert max(norms) > 0                                 # some iterations corrected an active set
    with pytest.raises(StepError, match="did not converge in 1 iterations"):
        simulate(membrane.problem(N=6), pair="P1+/P0", dt=1e-2, T=0.3, petsc_options={"snes_max_it": "1"})


def test_solver_monitor_prints_each_iteration(capfd):
    """-sdm_vi_monitor prints one line per semi-smooth Newton iteration (on rank 0)."""
    ts = simulate(membrane.problem(N=6), pair="P1+/P0", dt=1e-2, T=0.3,
                  petsc_options={"vi_monitor": "1"}).timeseries
    lines = [ln for ln in capfd.readouterr().out.splitlines() if "semi-smooth Newton:" in ln]
    if COMM.rank == 0:
        assert len(lines) == int(ts["newton_its"][1:].sum())
    else:
        assert lines == []

