"""The Python API: the README example, and a user-defined problem (demos/bar_problem.py) checked against its closed form."""
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import Pair, membrane, schemes, simulate
from sdm_dolfinx.method.pairs import PAIRS
from sdm_dolfinx.schemes import get as get_scheme

COMM = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parents[2]


def load_demo(name):
    """A demo script imported as a module (its ``__main__`` part does not run)."""
    spec = importlib.util.spec_from_file_location(f"demo_{name}", ROOT / "demos" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def clean_env():
    """The environment without the MPI job's variables, so that a child process is a fresh singleton."""
    keep = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "OMPI_MCA_btl")
    return {k: v for k, v in os.environ.items()
            if k in keep or not k.startswith(("OMPI_", "PMIX_", "OPAL_", "PRTE_", "HYDRA_", "PMI_"))}


# ------------------------------------------------------------------------------------------ the API
def test_readme_api_example():
    """The README's few lines (shortened to T = 0.3, dt = 1e-2), and pairs given as Pair objects."""
    problem = membrane.problem(N=8)
    result = simulate(problem, pair="P1+/P0", scheme="midpoint", dt=1e-2, T=0.3)
    ts = result.timeseries
    assert result.info["steps"] == 30 and len(ts["energy"]) == 31
    assert set(ts) >= {"t", "energy", "kinetic", "potential", "u_probe", "lambda_probe", "n_active"}
    assert np.all(np.isfinite(ts["energy"]))
    assert ts["n_active"][-1] > 0                         # the membrane reached the obstacle (t ~ 0.26)
    assert result.info["status"] == "finished" and result.info["pair"] == "P1+/P0"
    # a registered Pair object gives the same run; the same Problem can be run again
    again = simulate(problem, pair=PAIRS["P1+/P0"], scheme="midpoint", dt=1e-2, T=0.3)
    assert np.array_equal(again.timeseries["energy"], ts["energy"])
    # a pair of one's own (not registered): P2 displacement, P0 velocity
    own = simulate(membrane.problem(N=4), pair=Pair("P2/P0", ("P", 2), ("P", 0), "untested"), dt=1e-2, T=0.05)
    assert own.info["pair"] == "P2/P0" and own.info["dim_H"] == 2 * 4 * 4
    # every scheme by name; Result helpers
    for scheme in schemes.names():
        # explicit schemes need an invertible mass and a dt below their CFL bound: the diagonal P1 mass
        explicit = get_scheme(scheme).explicit
        kw = dict(pair="P1/P1", mass="row-sum", dt=1e-3, T=0.005) if explicit else dict(pair="P2/P1", dt=1e-2, T=0.05)
        r = simulate(membrane.problem(N=4, with_obstacle=False), scheme=scheme, **kw)
        assert r.info["scheme"] == scheme
    assert r.max_energy_deviation() < 1.0
    u = result.displacement()
    assert u.function_space == result.discretisation.W
    centre = COMM.allreduce(float(np.max(u.x.array)), op=MPI.MAX)
    assert centre == pytest.approx(0.02, abs=1e-12)        # the boundary value is the largest
    assert result.velocity().function_space == result.discretisation.H      # P1+/P0: the physical one
    assert result.vbar().function_space == result.discretisation.W


def test_unknown_names_are_refused():
    with pytest.raises(ValueError, match="unknown pair"):
        simulate(membrane.problem(N=2), pair="P3/P1", dt=1e-2, T=0.02)
    with pytest.raises(ValueError, match="unknown scheme"):
        simulate(membrane.problem(N=2), scheme="leapfrog", dt=1e-2, T=0.02)


# ---------------------------------------------------------------------- a problem not in the paper
def test_custom_problem_bar_matches_closed_form():
    """demos/custom_problem.py: an elastic bar (nu = 0) on a rigid wall, against the 1-D solution.

    Exact: contact from t0 = d/v for 2L/c, stress rho c v. Tolerances, checked on Nx x Ny =
    40 x 4 (measured with P2/P1, midpoint, dt = h/c, square cells Ny = Nx / 10):

    * duration within 2.5 %: the release happens at a step, and the reflected front is smeared
      by numerical dispersion over a few h/c; measured +2.5 % (2 steps) at Nx = 20, +1.25 %
      (1 step) at Nx = 40, +0.6 % at Nx = 80;
    * mean stress (impulse / duration / H) within 3 %: the bar leaves with a little energy in
      vibrations, so the rebound velocity and the impulse are a bit below 2 m v; the error is
      O(h): -2.9 % (Nx = 20), -1.55 % (Nx = 40), -0.8 % (Nx = 80); checked to shrink here;
    * plateau stress (median over the contact) within 0.5 %: measured -0.1 % and -0.04 %.
    Energy (no dissipation in the midpoint scheme with the singular mass) to 1e-9.
    """
    demo = load_demo("custom_problem")
    errors = {}
    for Nx in (20, 40):                       # square cells, h = L / Nx = H / Ny
        problem, result = demo.run("P2/P1", Nx=Nx, Ny=Nx // 10, cfl=1.0)
        ex, got = demo.closed_form(problem), demo.contact_measures(result, problem)
        errors[Nx] = abs(got["mean_stress"] / ex["stress"] - 1)
    dt = result.info["dt"]
    assert got["contiguous"]
    assert abs(got["t_first"] - ex["t0"]) <= dt * (1 + 1e-9)
    assert got["duration"] == pytest.approx(ex["duration"], rel=0.025)
    assert got["mean_stress"] == pytest.approx(ex["stress"], rel=0.03)
    assert got["plateau_stress"] == pytest.approx(ex["stress"], rel=0.005)
    assert result.max_energy_deviation() < 1e-9
    assert result.timeseries["contact_force"][-1] == 0.0       # it has left the wall
    assert errors[40] < 0.7 * errors[20]                       # O(h): measured ratio 0.53


def test_custom_problem_demo_runs_as_a_script(mpi_tmp_path):
    """``python demos/custom_problem.py`` as a user runs it (small mesh): exit 0, both numbers printed
    next to their closed forms, both pictures written (rank 0 starts a fresh serial process)."""
    problem = None
    if COMM.rank == 0:
        out = mpi_tmp_path / "bar"
        p = subprocess.run([sys.executable, str(ROOT / "demos" / "custom_problem.py"), "--Nx", "20", "--Ny", "2",
                            "--out", str(out)], capture_output=True, text=True, env=clean_env(), cwd=ROOT,
                           timeout=300)
        if p.returncode != 0:
            problem = f"demos/custom_problem.py failed ({p.returncode}):\n{p.stderr[-2000:]}"
        elif not ("2L/c" in p.stdout and "rho c v" in p.stdout):
            problem = f"demos/custom_problem.py did not print the comparison:\n{p.stdout}"
        else:
            missing = [f for f in ("bar_contact.png", "bar_wave.png", "P2-P1/timeseries.csv", "P2-P1/solution.xdmf")
                       if not (out / f).is_file()]
            problem = f"demos/custom_problem.py did not write {missing}" if missing else None
    problem = COMM.bcast(problem, root=0)
    assert problem is None, problem

