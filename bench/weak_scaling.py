"""A weak-scaling model of ``cg-pmg`` built from measured parts, not from one fitted slope.

A contact step of ``cg-pmg`` is k CG iterations (the solves per contact step of ``ball-window``); each
costs local work, halo exchanges and global reductions, and a V-cycle of GAMG on the P1 coarse problem:

    t_iter(P) = w n_local + S (alpha + h(n_local) / beta) + R 2 alpha log2(P) + L(P) alpha_level

* w: seconds per local dof and CG iteration, measured on 1 rank (the largest ``ball-window`` level:
  impact step time / solves per step / dofs);
* S, R: halo exchanges (PETSc VecScatterBegin) and global reductions per CG iteration, counted by
  ``--count`` under PETSc's log on 2-4 ranks (oversubscribed ranks count as well as real ones: the
  counts, not the times, are used), with h(n_local) the bytes per exchange and rank (measured, scaled as
  the partition's surface, n_local^(2/3));
* L(P): GAMG's levels on the P1 problem of P n_local / 8 dofs (measured at 1-4 ranks: one more level per
  coarsening by the measured ratio), each a few exchanges at latency alpha_level = 4 alpha;
* the network: alpha = 2 us latency, beta = 12.5 GB/s per link (InfiniBand HDR class), a reduction
  2 alpha log2(P) (a binary tree). Stated, not measured: this machine has no network.

Checked against what is measured here: the model's 2-rank time per CG iteration against the 2-rank
``ball-window`` rows (``--project`` prints both).

    mpirun -n 2 python bench/weak_scaling.py --count --level 3     # -> results/weak_counts_2.json
    python bench/weak_scaling.py --project                            # the table, results/weak_scaling.json
"""
import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

#: the stated network (module docstring)
ALPHA, BETA = 2e-6, 12.5e9
#: latency-bound exchanges per GAMG level and V-cycle (smoothing, restriction, interpolation)
LEVEL_EXCHANGES = 4
#: the projected rank counts, and the dofs per rank of the first table (a cluster run's typical load; the
#: second table keeps the largest level measured on 1 rank)
RANKS, N_LOCAL = (1, 8, 64, 512, 1000), 100_000
#: the events whose counts are the reductions (MPI_Allreduce inside) and the halo exchanges
REDUCTIONS = ("VecTDot", "VecDot", "VecNorm", "VecMDot", "VecMTDot", "VecDotNorm2")
EXCHANGE = "VecScatterBegin"


def count(level):
    """Per CG iteration of one free solve (random right-hand side) of the ball at ``level``: exchanges,
    messages, bytes, reductions; and GAMG's levels on the coarse P1 problem. Collective."""
    from mpi4py import MPI
    from petsc4py import PETSc
    from sdm_dolfinx.method.discretisation import Discretisation
    from sdm_dolfinx.problems import ball
    from sdm_dolfinx.run.integrator import Integrator
    comm = MPI.COMM_WORLD
    d = Discretisation(ball.problem(comm, level=level), "P2/P1")
    integ = Integrator(d, "midpoint", 4e-5, linear="cg-pmg")
    inner, K = integ.solver.inactive, integ.K
    b, x = K.createVecLeft(), K.createVecRight()
    lo, hi = K.getOwnershipRange()
    b.array[:] = np.random.default_rng(3).standard_normal(K.getSize()[0])[lo:hi]
    PETSc.Log.begin()
    events = {name: PETSc.Log.Event(name) for name in (EXCHANGE, *REDUCTIONS)}
    before = {name: e.getPerfInfo() for name, e in events.items()}
    its0 = inner.its
    inner.solve(b, x, np.zeros(len(inner.cdofs), dtype=bool), [K.createVecLeft() for _ in range(3)])
    its = inner.its - its0
    after = {name: e.getPerfInfo() for name, e in events.items()}
    diff = {name: {k: after[name][k] - before[name][k] for k in ("count", "numMessages", "messageLength")}
            for name in events}
    coarse_pc = inner.ksp_amg.getPC().getMGCoarseSolve().getPC()
    gamg_levels = coarse_pc.getMGLevels()
    coarse_rows = inner.ksp_amg.getPC().getMGCoarseSolve().getOperators()[0].getSize()[0]
    sc = diff[EXCHANGE]
    out = {"level": level, "ranks": comm.size, "dofs": K.getSize()[0], "n_local_max": comm.allreduce(hi - lo, op=MPI.MAX),
           "cg_iterations": its, "exchanges_per_it": sc["count"] / its,
           "messages_per_it": comm.allreduce(sc["numMessages"], op=MPI.MAX) / its,
           "bytes_per_exchange": (comm.allreduce(sc["messageLength"], op=MPI.MAX) / max(sc["count"], 1)),
           "reductions_per_it": sum(diff[n]["count"] for n in REDUCTIONS) / its,
           "gamg_levels": gamg_levels, "coarse_rows": coarse_rows}
    integ.destroy()
    return out


def _window(path, strategy="cg-pmg"):
    """{ranks: [(dofs, s per contact step, solves per contact step)]} of the recorded ball-window rows."""
    recs = json.loads(path.read_text())["records"]
    out = {}
    for r in recs:
        if r.get("status") == "finished" and r["strategy"] == strategy:
            out.setdefault(r["ranks"], []).append((r["dofs"], r["step_time_impact"], r["linear_per_step_impact"]))
    return {p: sorted(v) for p, v in out.items()}


def model(w, counts, n_local, ranks, k):
    """Seconds per contact step of k CG iterations on ``ranks`` ranks of ``n_local`` dofs each (docstring)."""
    ref = max(counts, key=lambda c: c["ranks"])          # the most ranks counted
    halo = ref["bytes_per_exchange"] * (n_local / ref["n_local_max"]) ** (2.0 / 3.0)
    exchanges = ref["exchanges_per_it"] if ranks > 1 else 0.0
    levels = counts[0]["gamg_levels"] + max(0.0, math.log(ranks) / math.log(8.0))    # one more per 8x
    t = (w * n_local + exchanges * (ALPHA + halo / BETA) + ref["reductions_per_it"] * 2 * ALPHA * math.log2(max(ranks, 1))
         + (levels * LEVEL_EXCHANGES * ALPHA if ranks > 1 else 0.0))
    return k * t, {"local": k * w * n_local, "halo": k * exchanges * (ALPHA + halo / BETA),
                   "reductions": k * ref["reductions_per_it"] * 2 * ALPHA * math.log2(max(ranks, 1))}


def project(out):
    window = _window(out / "ball-window.json")
    counts = [json.loads(p.read_text()) for p in sorted(out.glob("weak_counts_*.json"))]
    if 1 not in window or not counts:
        print("weak_scaling: needs ball-window.json with 1-rank cg-pmg rows and weak_counts_*.json (--count)",
              file=sys.stderr)
        return 2
    counts.sort(key=lambda c: c["ranks"])
    n1, t1, k1 = window[1][-1]                            # the largest level on 1 rank
    w = t1 / k1 / n1
    # CG iterations per contact step grow with the mesh: more contact vertices, more Newton iterations per step
    # (each solve's count stays nearly constant): k(N) = k1 (N / n1)^s fitted over the levels measured
    pts = [(n, s) for n, _, s in window[1]]
    sk = float(np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)[0])
    k1 = pts[-1][1]

    def k_of(dofs):
        return k1 * (dofs / n1) ** sk
    print(f"w = {w:.3g} s per dof and CG iteration (1 rank, {n1} dofs); CG iterations per contact step "
          f"{', '.join(f'{s:.1f}' for _, s in pts)} at {', '.join(str(n) for n, _ in pts)} dofs: k(N) = {k1:.1f} "
          f"(N / {n1})^{sk:.3f}")
    for c in counts:
        print(f"{c['ranks']} ranks (level {c['level']}, {c['dofs']} dofs): {c['exchanges_per_it']:.1f} exchanges, "
              f"{c['reductions_per_it']:.1f} reductions per CG iteration, {c['bytes_per_exchange'] / 1e3:.1f} kB per "
              f"exchange and rank, GAMG {c['gamg_levels']} levels on {c['coarse_rows']} coarse rows")
    checks = []
    for n, t, s in window.get(2, []):
        pred, _ = model(w, counts, n / 2, 2, s)
        checks.append({"dofs": n, "measured": t, "model": pred})
        print(f"check, 2 ranks, {n} dofs: measured {t:.2f} s per contact step, model {pred:.2f} s (no network term "
              f"is measurable here: shared memory)")
    rows = []
    for n_local in (N_LOCAL, n1):
        print(f"\n{n_local / 1e3:.0f}k dofs per rank:\n\n| ranks | dofs | CG its per step | s per contact step | local | "
              f"halo | reductions | efficiency | efficiency at fixed its |\n|---|---|---|---|---|---|---|---|---|")
        t_one, _ = model(w, counts, n_local, 1, k_of(n_local))
        for p in RANKS:
            k = k_of(p * n_local)
            t, parts = model(w, counts, n_local, p, k)
            fixed, _ = model(w, counts, n_local, p, k_of(n_local))
            rows.append({"n_local": n_local, "ranks": p, "dofs": p * n_local, "k": k, "s": t, **parts,
                         "efficiency": t_one / t, "efficiency_fixed_k": t_one / fixed})
            print(f"| {p} | {p * n_local / 1e6:.3g} M | {k:.0f} | {t:.3g} | {parts['local']:.3g} | {parts['halo']:.3g} | "
                  f"{parts['reductions']:.2g} | {t_one / t:.2f} | {t_one / fixed:.3f} |")
    (out / "weak_scaling.json").write_text(json.dumps({"w": w, "k1": k1, "k_slope": sk, "n1": n1, "alpha": ALPHA, "beta": BETA, "counts": counts,
                                                       "checks": checks, "rows": rows}, indent=1))
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", action="store_true", help="count exchanges and reductions (run under mpirun)")
    ap.add_argument("--level", type=int, default=3, help="the ball's level for --count (default 3)")
    ap.add_argument("--project", action="store_true", help="print and write the model's table")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="results folder")
    args = ap.parse_args(argv)
    if args.count:
        from mpi4py import MPI
        c = count(args.level)
        if MPI.COMM_WORLD.rank == 0:
            (args.out / f"weak_counts_{c['ranks']}.json").write_text(json.dumps(c, indent=1))
            print(json.dumps(c))
        return 0
    if args.project:
        return project(args.out)
    ap.print_usage()
    return 2


if __name__ == "__main__":
    sys.exit(main())
