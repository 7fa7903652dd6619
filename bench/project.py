"""The 3-D ball's measured curves, fitted and projected to a cluster run (README "Large runs").

Reads ``results/ball.json`` (75-step bounces, ``auto`` = ``schur`` at levels 1-4) and
``results/ball-window.json`` (6 steps from first contact, ``schur``, ``cg-gamg`` and ``cg-pmg``) and fits,
for each strategy on 1 rank, time per contact step = a n^s (least squares in log-log over the
levels measured); memory per rank comes from :mod:`sdm_dolfinx.solvers.memory`'s fits of the same
runs' peaks. At ``--dofs`` (default 10 M) it prints, for each strategy and rank count, the
memory per rank (ideal: the total divided by the ranks; and with memory.SHARED, the share that
did not halve from 1 to 2 ranks, kept on every rank) and the time per contact step under two
stated assumptions, both projections:

* ideal: the 1-rank time divided by the ranks;
* measured efficiency: each doubling of the ranks gains what 1 -> 2 ranks gained at the largest
  level measured, at most 2 (one doubling on one 2-core node: no network, a memory bus that
  favours the second rank, and MUMPS's solves at their least parallel: the assumption's weakness).

    python bench/project.py                       # the table for 10 M dofs
    python bench/project.py --dofs 3e6 --ranks 16 64

Writes ``results/projection.json`` (the fits and the table).
"""
import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from sdm_dolfinx.solvers import memory  # noqa: E402


def records(out):
    """Finished 3-D records of the ball suites: (suite, record)."""
    recs = []
    for name in ("ball", "ball-window"):
        path = out / f"{name}.json"
        if path.exists():
            recs += [(name, r) for r in json.loads(path.read_text())["records"] if r.get("status") == "finished"]
    return recs


def curves(recs):
    """strategy -> {ranks: [(dofs, s per contact step)]},
    ``schur`` from the bounces (``auto`` chose it), ``cg-gamg`` and ``cg-pmg`` from the window."""
    cur = {}
    for suite, r in recs:
        strat = r.get("linear_strategy") or ("schur" if r["strategy"] == "auto" else r["strategy"])
        if (strat, suite) not in (("schur", "ball"), ("cg-gamg", "ball-window"), ("cg-pmg", "ball-window")):
            continue
        cur.setdefault(strat, {}).setdefault(r["ranks"], []).append((r["dofs"], r["step_time_impact"]))
    return {s: {p: sorted(v) for p, v in by.items()} for s, by in cur.items()}


def fit(points):
    """(a, s) of t = a n^s, least squares in log-log."""
    n, t = np.array([p[0] for p in points], float), np.array([p[1] for p in points], float)
    s, loga = np.polyfit(np.log(n), np.log(t), 1)
    return float(math.exp(loga)), float(s)


def project(cur, dofs, ranks):
    """The fits and the projected rows (see the module's docstring)."""
    fits, rows = {}, []
    for strat, by in sorted(cur.items()):
        a, s = fit(by[1])
        one, two = dict(by[1]), dict(by.get(2, []))
        n2 = max(one.keys() & two.keys(), default=None)
        gain = one[n2] / two[n2] if n2 else None
        fits[strat] = {"a": a, "s": s, "levels": [p[0] for p in by[1]], "two_rank_gain": gain, "at_dofs": n2}
        total = memory.run_bytes(dofs, 3, factorised=(strat == "schur"))
        t1 = a * dofs ** s
        for p in ranks:
            rows.append({"strategy": strat, "ranks": p, "gb_per_rank": (total / p + memory.BYTES_PER_PROCESS) / 1e9,
                         "gb_per_rank_shared": (memory.per_rank(total, p) + memory.BYTES_PER_PROCESS) / 1e9,
                         "s_ideal": t1 / p, "s_measured_eff": t1 / min(gain, 2.0) ** math.log2(p) if gain else None,
                         "rank_s": t1})
    return fits, rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dofs", type=float, default=1e7, help="dim W^h of the projected run (default 1e7)")
    ap.add_argument("--ranks", type=int, nargs="+", default=[64, 256, 1024], help="rank counts (default 64 256 1024)")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="results folder")
    args = ap.parse_args(argv)
    cur = curves(records(args.out))
    if not all(1 in by for by in cur.values()) or len(cur) < 2:
        print("project: needs ball.json and ball-window.json with 1-rank schur and cg-gamg records", file=sys.stderr)
        return 2
    fits, rows = project(cur, args.dofs, args.ranks)
    for strat, f in fits.items():
        gain = "-" if f["two_rank_gain"] is None else f"{f['two_rank_gain']:.2f}x at {f['at_dofs']} dofs"
        print(f"{strat:8s} t = {f['a']:.3g} n^{f['s']:.2f} s per contact step (1 rank, n = {f['levels']}); "
              f"2 ranks: {gain}")
    print("\n| strategy | ranks | GB per rank, ideal (total / ranks + one process) | GB per rank, 2-rank share "
          "kept | s per contact step, ideal | at the measured 2-rank efficiency |\n|---|---|---|---|---|---|")
    for r in rows:
        eff = "-" if r["s_measured_eff"] is None else f"{r['s_measured_eff']:.3g}"
        print(f"| {r['strategy']} | {r['ranks']} | {r['gb_per_rank']:.3g} | {r['gb_per_rank_shared']:.3g} | "
              f"{r['s_ideal']:.3g} | {eff} |")
    (args.out / "projection.json").write_text(json.dumps({"dofs": args.dofs, "fits": fits, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
