"""The cost of contact between two deformable bodies: the share of the contact search and the rows.

The target: the contact search and the two-body constraint assembly at most 10 % of a step at
the size of ball level 4. Each case runs two equal balls head on (the built-in two_balls, P2/P1,
midpoint, ``linear="schur"``) from 4 um apart each (contact from the first steps), 6 steps, in a fresh
process, the median of 3 runs; per case: the mean time of a step with active contact (the Integrator's
``step``: the set-up excluded, the steps that compute the columns of newly active rows included), the
time of the rows (:meth:`BodyRows.rows`: the deformed master facets near each rank's slave vertices
sent to it, every slave vertex projected, the rows assembled) and of the end-of-step gap (a second projection), and their share of the
steps, and the most facets a rank received in the last projection (the whole surface before the
facets were sent by bounding boxes: "facets sent to a rank"). ``--friction``: ball 1 also moves across at 100 mm/s (an oblique collision) under Coulomb friction
(mu = 0.3): the rows carry their tangential rows too, and the frictional solver gathers every rank's rows
into one matrix every step (``NodeFrames.set_rows``: its time is the column "rows matrix"). ``--weighted``:
the weighted gap (``constrain="weighted"``, :mod:`sdm_dolfinx.method.weighted_body_rows`): every node of the
slave faces projected, each node's row sent to the owners of the vertices it enters.

    .venv/bin/python bench/two_bodies.py                        # levels 1-3, 1 rank; results/two_bodies.json
    .venv/bin/python bench/two_bodies.py --ranks 2 --level 3
    .venv/bin/python bench/two_bodies.py --friction --level 3
    .venv/bin/python bench/two_bodies.py --weighted --level 3
    .venv/bin/python bench/two_bodies.py --table
"""
import argparse
import json
import sys
import time
from pathlib import Path

from fresh import median_of_fresh_runs

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "two_bodies.json"
LEVELS = (1, 2, 3)
STEPS, DT, HEIGHT = 6, 4e-5, 0.004
REPEATS = 3


def one(level, friction=False, weighted=False):
    """Run one case in this process (``friction``: oblique, Coulomb mu = 0.3; ``weighted``: the weighted gap);
    returns its record."""
    from mpi4py import MPI
    import numpy as np
    from sdm_dolfinx.method import body_rows, weighted_body_rows
    from sdm_dolfinx.method.discretisation import Discretisation
    from sdm_dolfinx.contact.friction import make as make_friction
    from sdm_dolfinx.problems import two_balls
    from sdm_dolfinx.run.integrator import Integrator
    from sdm_dolfinx.solvers import friction_frames

    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    p = two_balls.problem(comm, level=level, height=HEIGHT, vt=100.0 if friction else 0.0)
    spent = {"rows": 0.0, "gap": 0.0, "matrix": 0.0}

    def timed(name, f):
        def wrapper(self, *a, **k):
            s = time.perf_counter()
            out = f(self, *a, **k)
            spent[name] += time.perf_counter() - s
            return out
        return wrapper
    body_rows.BodyRows.rows = timed("rows", body_rows.BodyRows.rows)
    weighted_body_rows.WeightedBodyRows.rows = timed("rows", weighted_body_rows.WeightedBodyRows.rows)
    body_rows.BodyRows.after_step = timed("gap", body_rows.BodyRows.after_step)
    friction_frames.NodeFrames.set_rows = timed("matrix", friction_frames.NodeFrames.set_rows)
    d = Discretisation(p, "P2/P1", constrain="weighted" if weighted else "vertices")
    integ = Integrator(d, "midpoint", DT, linear="schur", friction=make_friction("coulomb", 0.3) if friction else None)
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    setup = time.perf_counter() - t0
    times, actives = [], []
    for n in range(STEPS):
        comm.Barrier()
        s = time.perf_counter()
        info = integ.step(U, V, n, n * DT)
        comm.Barrier()
        times.append(time.perf_counter() - s)
        actives.append(int(info["n_active"]))
    contact = [t for t, a in zip(times, actives) if a > 0]
    surface = d.body_rows.surfaces[0]
    received = comm.allreduce(surface.received, op=MPI.MAX)          # the last projection's, the most a rank got
    integ.destroy()
    return {"level": level, "ranks": comm.size, "friction": bool(friction), "weighted": bool(weighted), "matrix_s": spent["matrix"], "dim_W": d.dims()["dim_W"], "slave_vertices": d.num_constraints,
            "master_facets": len(d.body_rows.surfaces[0].cells), "setup_s": setup, "step_s": times,
            "n_active": actives, "contact_step_s": float(np.mean(contact)) if contact else None,
            "rows_s": spent["rows"], "gap_s": spent["gap"], "facets_received": received}


def run_fresh(level, ranks, friction=False, weighted=False):
    """One record from a fresh process (the median time of REPEATS runs)."""
    return median_of_fresh_runs(__file__, ["--one", level] + (["--friction"] if friction else [])
                                + (["--weighted"] if weighted else []), ranks, REPEATS)


def _key(r):
    return r["level"], r["ranks"], r.get("friction", False), r.get("weighted", False)


def table(results):
    lines = ["| level | ranks | friction | gap | dim W^h | slave vertices | master facets | active (last step) | "
             "facets sent to a rank | contact step (s) | rows (s/step) | rows matrix (s/step) | end gap (s/step) | "
             "search and rows / step | set-up (s) |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(results, key=_key):
        steps, mat = sum(r["step_s"]), r.get("matrix_s", 0.0)
        lines.append(f"| {r['level']} | {r['ranks']} | {'Coulomb' if r.get('friction') else '-'} | "
                     f"{'weighted' if r.get('weighted') else 'vertices'} | {r['dim_W']} | "
                     f"{r['slave_vertices']} | {r['master_facets']} | {r['n_active'][-1]} | {r.get('facets_received', '-')} | "
                     f"{r['contact_step_s']:.4f} | "
                     f"{r['rows_s'] / STEPS:.4f} | {mat / STEPS:.4f} | {r['gap_s'] / STEPS:.4f} | "
                     f"{(r['rows_s'] + r['gap_s'] + mat) / steps:.1%} | {r['setup_s']:.1f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=int, action="append", choices=(1, 2, 3, 4))
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--friction", action="store_true", help="an oblique collision under Coulomb friction (mu 0.3)")
    ap.add_argument("--weighted", action="store_true", help="the weighted gap (constrain weighted)")
    ap.add_argument("--table", action="store_true", help="print the table of the recorded results")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        rec = one(args.one, args.friction, args.weighted)
        from mpi4py import MPI
        if MPI.COMM_WORLD.rank == 0:
            print(json.dumps(rec))
        sys.exit(0)
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else []
    if not args.table:
        for level in args.level or LEVELS:
            rec = run_fresh(level, args.ranks, args.friction, args.weighted)
            results = [r for r in results if _key(r) != _key(rec)] + [rec]
            print(f"level {level} ranks {args.ranks}: contact step {rec['contact_step_s']:.4f} s (repeats "
                  f"{', '.join(f'{t:.4f}' for t in rec['repeats'])})", flush=True)
            RESULTS.parent.mkdir(exist_ok=True)
            RESULTS.write_text(json.dumps(results, indent=1))
    print(table(results))
