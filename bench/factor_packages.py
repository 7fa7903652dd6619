"""What a PETSc without SuiteSparse costs: the step matrix's factorisation by CHOLMOD against MUMPS.

A run factorises its step matrix K once (``schur``, ``cg-factor``) with the package
:func:`sdm_dolfinx.solvers.factorisation.factor_package` chooses: CHOLMOD on one process where
PETSc has SuiteSparse, else MUMPS (the PyPI wheel dolfinx-solver-real has no SuiteSparse). P2/P1
from 20 000 rows factorises the sparser augmented matrix instead, by MUMPS LDL^T either way. For
each case, on one rank, this times the factorisation and one solve (median of ``--solves``
solves with random right-hand sides):

* ``run``: what the run factorises (K or the augmented matrix), with SuiteSparse and with
  :func:`sdm_dolfinx.compat.petsc_has` made to say it is absent (as on the wheel);
* ``membrane-run:N``: the whole membrane run of the ``membrane`` suite (400 steps) both ways;
* ``K``: K itself by CHOLMOD and by MUMPS (Cholesky), where the run does not factorise K (up to
  :data:`K_MAX_NNZ` nonzeros).

The two solutions of each pair must agree to round-off (relative 1e-8 of the solution's size:
far below the tests' 1e-10 on whole runs because those compare time series, not one solve).

    .venv/bin/python bench/factor_packages.py                  # the recorded cases -> results/factor_packages.json
    .venv/bin/python bench/factor_packages.py --cases disc:2 --out /tmp/f.json
"""
import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: case -> (problem module, size parameter, pair, dt): the step matrices of the recorded suites
CASES = {"membrane": ("membrane", "N", "P1+/P0", 1e-3), "disc": ("disc", "level", "P2/P1", 5e-5),
         "ball": ("ball", "level", "P2/P1", 4e-5)}
DEFAULT = ["membrane:80", "membrane-run:80", "disc:3", "disc:4", "ball:2", "ball:3"]
AGREE = 1e-8
#: K itself is factorised for comparison only up to this many nonzeros (the ball at level 2 has
#: 14.6 M: 37-50 s; at level 3 the run factorises only the augmented matrix)
K_MAX_NNZ = 20_000_000


def timed(K, aug, solves, absent=()):
    """(package, factorisation s, median solve s, solution) of one Factorisation of K (through
    ``aug`` if given) on a PETSc said to lack ``absent``."""
    from petsc4py import PETSc
    import numpy as np
    from sdm_dolfinx import compat
    from sdm_dolfinx.solvers.factorisation import Factorisation
    real = compat.petsc_has
    compat.petsc_has = lambda package: package not in absent and real(package)
    try:
        t0 = time.perf_counter()
        fac = Factorisation(K, True, "bench_factor_", aug=aug)
        t_factor = time.perf_counter() - t0
    finally:
        compat.petsc_has = real
    r, x = K.createVecLeft(), K.createVecRight()
    rng = np.random.default_rng(1)
    times = []
    for _ in range(solves):
        r.array[:] = rng.standard_normal(r.getLocalSize())
        t0 = time.perf_counter()
        fac.solve(r, x)
        times.append(time.perf_counter() - t0)
    r.array[:] = np.random.default_rng(0).standard_normal(r.getLocalSize())
    fac.solve(r, x)
    out = (fac.package, t_factor, statistics.median(times), x.array.copy())
    fac.destroy()
    r.destroy()
    x.destroy()
    PETSc.garbage_cleanup() if hasattr(PETSc, "garbage_cleanup") else None
    return out


def whole_run(N, absent=()):
    """(factor_package, wall s, energy series) of the membrane P1+/P0 run of the ``membrane``
    suite (bench/run.py: dt = 1e-3, T = 0.4, contact from step 259) at size N, ``auto``."""
    from mpi4py import MPI
    from sdm_dolfinx import compat, membrane, simulate
    real = compat.petsc_has
    compat.petsc_has = lambda package: package not in absent and real(package)
    try:
        t0 = time.perf_counter()
        r = simulate(membrane.problem(MPI.COMM_SELF, N=N), pair="P1+/P0", dt=1e-3, T=0.4)
        wall = time.perf_counter() - t0
    finally:
        compat.petsc_has = real
    return r.info["factor_package"], wall, r.timeseries["energy"].copy()


def measure_run(N):
    """The record of case ``membrane-run:N``: the whole run with and without SuiteSparse."""
    import numpy as np
    (pa, wa, ea), (pb, wb, eb) = whole_run(N), whole_run(N, ("suitesparse",))
    diff = float(np.max(np.abs(ea - eb)) / np.max(np.abs(ea)))
    assert diff < 1e-10, f"membrane-run:{N}: energies differ by {diff:.1e}"
    return {"case": f"membrane-run:{N}", "with_suitesparse": {"package": pa, "run_s": round(wa, 2)},
            "without_suitesparse": {"package": pb, "run_s": round(wb, 2)}, "energy_relative_difference": diff}


def measure(case, solves):
    """The record of one case ``name:size`` (see the module's docstring)."""
    from mpi4py import MPI
    import numpy as np
    import importlib
    from sdm_dolfinx.method.discretisation import Discretisation
    from sdm_dolfinx.run.integrator import Integrator
    name, size = case.split(":")
    module, param, pair, dt = CASES[name]
    problem = importlib.import_module(f"sdm_dolfinx.problems.{module}").problem(MPI.COMM_SELF, **{param: int(size)})
    t0 = time.perf_counter()
    d = Discretisation(problem, pair)
    integ = Integrator(d, "midpoint", dt, linear="auto" if name != "ball" else "schur")
    setup = time.perf_counter() - t0
    K, aug = integ.K, integ.factor_matrix
    integ.solver.destroy()          # its own factorisation: not to be held twice in memory
    rec = {"case": case, "pair": pair, "rows_K": K.getSize()[0], "nnz_K": int(K.getInfo()["nz_used"]),
           "rows_aug": aug.getSize()[0] if aug is not None else None,
           "nnz_aug": int(aug.getInfo()["nz_used"]) if aug is not None else None, "integrator_setup_s": round(setup, 2)}
    pairs = {"run": [timed(K, aug, solves), timed(K, aug, solves, ("suitesparse",))]}
    if aug is not None and rec["nnz_K"] <= K_MAX_NNZ:
        pairs["K"] = [timed(K, None, solves), timed(K, None, solves, ("suitesparse",))]
    for what, ((pa, fa, sa, xa), (pb, fb, sb, xb)) in pairs.items():
        diff = float(np.max(np.abs(xa - xb)) / np.max(np.abs(xa)))
        assert diff < AGREE, f"{case} {what}: {pa} and {pb} differ by {diff:.1e}"
        rec[what] = {"with_suitesparse": {"package": pa, "factor_s": round(fa, 4), "solve_ms": round(1e3 * sa, 3)},
                     "without_suitesparse": {"package": pb, "factor_s": round(fb, 4), "solve_ms": round(1e3 * sb, 3)},
                     "relative_difference": diff}
    return rec


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(DEFAULT), help="comma-separated name:size (membrane:N, disc:level, "
                                                                "ball:level)")
    ap.add_argument("--solves", type=int, default=10)
    ap.add_argument("--out", default=str(HERE / "results" / "factor_packages.json"))
    args = ap.parse_args(argv)
    import petsc4py
    import dolfinx
    records = []
    for case in args.cases.split(","):
        load = os.getloadavg()[0]
        rec = (measure_run(int(case.split(":")[1])) if case.startswith("membrane-run:")
               else measure(case, args.solves))
        rec["load_before"], rec["load_after"] = round(load, 2), round(os.getloadavg()[0], 2)
        print(json.dumps(rec), flush=True)
        records.append(rec)
    env = {"date": time.strftime("%Y-%m-%d"), "dolfinx": dolfinx.__version__, "petsc4py": petsc4py.__version__,
           "python": sys.version.split()[0], "ranks": 1}
    Path(args.out).write_text(json.dumps({"environment": env, "records": records}, indent=1) + "\n")


if __name__ == "__main__":
    main()
