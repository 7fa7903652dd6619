"""The cost of the general gap rows: the plane as a signed distance against the plane as a bound.

The issue's targets: the gap rows (obstacles: :mod:`sdm_dolfinx.method.obstacle_rows` and
:mod:`sdm_dolfinx.solvers.gap_newton`) at most 1.2 times today's time per contact step at disc
level 5 and ball level 4, and the obstacle projection (the signed distances and normals of every
step's rows) at most 5 % of a step.

Each case runs the same problem twice, in a fresh process each, with the step solver's one
factorisation for the run (``linear="schur"``):

* ``bound``: the built-in problem, its foundation the bound ``lower_bound`` (the semi-smooth Newton
  on unit rows, :mod:`sdm_dolfinx.solvers.schur`);
* ``plane``: the same with ``lower_bound=None, obstacles=[HalfSpace(...)]`` (the gap-row Newton, the
  rows recomputed before every step from the signed distance);
* ``bound-coulomb``, ``plane-coulomb`` (``--friction``): both with Coulomb friction, mu = 0.3: the
  frictional Newton on the axis-aligned dofs, or in each node's frame (its columns combined and
  rotated every step: :mod:`sdm_dolfinx.solvers.friction_system`).

The windows of bench/run.py: disc level 5 from 0.02 mm above the foundation (contact from the first
step, 3 steps); the ball from 4 um above the plane (contact from step 2, 6 steps), levels 3 and 4.
Per case: the mean time of a step with active contact (the Integrator's ``step`` only; the set-up
excluded; the steps that compute the columns of newly active rows included, as in bench/run.py's
impact phase), the time spent in the rows' projection, the set-up time.

    .venv/bin/python bench/gap_rows.py                  # every case, results/gap_rows.json, a table
    .venv/bin/python bench/gap_rows.py --case disc5     # one case
    .venv/bin/python bench/gap_rows.py --friction --case disc5 --case ball3   # the frictional variants
    .venv/bin/python bench/gap_rows.py --table          # the table of the recorded results
"""
import argparse
import json
import sys
import time
from pathlib import Path

from fresh import median_of_fresh_runs

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "gap_rows.json"
CASES = {
    "disc5": {"problem": "disc", "level": 5, "height": 0.02, "dt": 5e-5, "steps": 3, "normal": (0.0, 1.0)},
    "ball3": {"problem": "ball", "level": 3, "height": 0.004, "dt": 4e-5, "steps": 6, "normal": (0.0, 0.0, 1.0)},
    "ball4": {"problem": "ball", "level": 4, "height": 0.004, "dt": 4e-5, "steps": 6, "normal": (0.0, 0.0, 1.0)},
}
REPEATS = 3


def one(case, variant):
    """Run one variant of one case in this process; returns its record."""
    from mpi4py import MPI
    import numpy as np
    from sdm_dolfinx.method import obstacle_rows
    from sdm_dolfinx.method.discretisation import Discretisation
    from sdm_dolfinx.obstacles import HalfSpace
    from sdm_dolfinx.problems import ball, disc
    from sdm_dolfinx.run.integrator import Integrator
    from sdm_dolfinx.contact.friction import make as make_friction

    spec = CASES[case]
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    mod = {"disc": disc, "ball": ball}[spec["problem"]]
    p = mod.problem(comm, level=spec["level"], height=spec["height"])
    if variant.startswith("plane"):
        p.lower_bound = None
        p.obstacles = [HalfSpace(np.zeros(len(spec["normal"])), spec["normal"])]
    projection = [0.0]
    rows_of = obstacle_rows.ObstacleRows.rows

    def timed(self, *a, **k):
        s = time.perf_counter()
        out = rows_of(self, *a, **k)
        projection[0] += time.perf_counter() - s
        return out
    obstacle_rows.ObstacleRows.rows = timed
    d = Discretisation(p, "P2/P1")
    friction = make_friction("coulomb", mu=0.3) if variant.endswith("coulomb") else None
    integ = Integrator(d, "midpoint", spec["dt"], linear="schur", friction=friction)
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    setup = time.perf_counter() - t0
    times, actives = [], []
    for n in range(spec["steps"]):
        comm.Barrier()
        s = time.perf_counter()
        info = integ.step(U, V, n, n * spec["dt"])
        comm.Barrier()
        times.append(time.perf_counter() - s)
        actives.append(int(info["n_active"]))
    contact = [t for t, a in zip(times, actives) if a > 0]
    energy = sum(integ.energies(U, V, spec["steps"] * spec["dt"]))
    integ.destroy()
    return {"case": case, "variant": variant, "ranks": comm.size, "dim_W": d.dims()["dim_W"],
            "setup_s": setup, "step_s": times, "n_active": actives,
            "contact_step_s": float(np.mean(contact)) if contact else None,
            "projection_s": projection[0], "energy_end": float(energy)}


def run_fresh(case, variant, ranks):
    """One record from a fresh process (the median time of REPEATS runs)."""
    return median_of_fresh_runs(__file__, ["--one", case, variant], ranks, REPEATS)


def table(results):
    lines = ["| case | ranks | dim W^h | active (last step) | contact step, bound (s) | contact step, plane (s) | plane / bound | "
             "projection / plane step | final energy, plane / bound - 1 |",
             "|---|---|---|---|---|---|---|---|---|"]
    for key in sorted({(r["case"], r["ranks"], r["variant"].partition("-")[2]) for r in results}):
        by = {r["variant"].partition("-")[0]: r for r in results
              if (r["case"], r["ranks"], r["variant"].partition("-")[2]) == key}
        if set(by) != {"bound", "plane"}:
            continue
        b, p = by["bound"], by["plane"]
        key = (key[0] + (f", {key[2]}" if key[2] else ""), key[1])
        steps = sum(1 for a in p["n_active"] if a > 0)
        share = p["projection_s"] / max(sum(p["step_s"]), 1e-300)
        lines.append(f"| {key[0]} | {key[1]} | {b['dim_W']} | {p['n_active'][-1]} | {b['contact_step_s']:.4f} | "
                     f"{p['contact_step_s']:.4f} | {p['contact_step_s'] / b['contact_step_s']:.2f} | {share:.1%} | "
                     f"{p['energy_end'] / b['energy_end'] - 1:+.1e} |" + ("" if steps else " (no contact)"))
    return "\n".join(lines)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", action="append", choices=sorted(CASES))
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--table", action="store_true", help="print the table of the recorded results")
    ap.add_argument("--friction", action="store_true", help="the variants with Coulomb friction (mu = 0.3)")
    ap.add_argument("--one", nargs=2, metavar=("CASE", "VARIANT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        rec = one(*args.one)
        from mpi4py import MPI
        if MPI.COMM_WORLD.rank == 0:
            print(json.dumps(rec))
        sys.exit(0)
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else []
    if not args.table:
        for case in args.case or sorted(CASES):
            for variant in (("bound-coulomb", "plane-coulomb") if args.friction else ("bound", "plane")):
                rec = run_fresh(case, variant, args.ranks)
                results = [r for r in results if (r["case"], r["variant"], r["ranks"]) !=
                           (case, variant, args.ranks)] + [rec]
                print(f"{case} {variant} ranks {args.ranks}: contact step {rec['contact_step_s']:.4f} s "
                      f"(repeats {', '.join(f'{t:.4f}' for t in rec['repeats'])})", flush=True)
                RESULTS.parent.mkdir(exist_ok=True)
                RESULTS.write_text(json.dumps(results, indent=1))
    print(table(results))
