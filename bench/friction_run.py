"""Benchmark of the disc with Coulomb friction against the same run without friction.

The disc of the paper (P2/P1, C lumped, midpoint) at levels 1-5 with the Table 2 time step of
each level, dt = 8e-4 / 2^(L-1) s, to T = 0.02 s (25 ... 400 steps), thrown obliquely
(vx0 = 300 mm/s, v0 = -1000 mm/s: the tangential velocity is 0.3 of the normal one, so
vertices slip at mu = 0.3 while the contact zone spreads), once with Coulomb friction
(mu = 0.3, :class:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton`) and once without
(the default ``--linear auto``: ``schur``), on 1 and 2 ranks. Each case runs in a fresh
process (``mpirun -n 2`` for 2 ranks, the environment of :func:`bench.run.spawn`) and
records: mesh and set-up time, the *median* time per step in free flight and in contact (a
step is in contact when a vertex is active after it), the mean over the contact steps, the
first contact step apart (it solves the cached columns of K^-1), Newton iterations per step
(mean over all steps, mean and max over the contact steps), the numbers of sticking and
slipping vertices in contact (mean, max; steps with a slipping vertex), solves with the
factorisation per step, the peak resident memory of every rank, and the load average.
Runs shorter than ``--short`` s are repeated and each timing is the median over the
repetitions. The summary gives, per level and rank count, the ratio friction / frictionless
of the median time per contact step (the target: <= 2 at level 5).

    .venv/bin/python bench/friction_run.py                  # levels 1-5, 1 and 2 ranks (~15 min)
    .venv/bin/python bench/friction_run.py --levels 1 2 --ranks 1 --out /tmp/f
    .venv/bin/python bench/friction_run.py --table          # the markdown table of the results
    .venv/bin/python bench/friction_run.py --plot-only      # redraw bench/friction_time_per_step.png

Results: ``bench/results/disc_friction.json`` and ``bench/friction_time_per_step.png``.
"""
import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def _bench_run():
    """bench/run.py as a module (its peak memory, environment and formatting helpers)."""
    spec = importlib.util.spec_from_file_location("bench_run", HERE / "run.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


BR = _bench_run()

#: the suite: the disc thrown obliquely; dt of level L = DT1 / 2^(L-1) (Table 2 of the paper)
SUITE = {"problem": "disc", "pair": "P2/P1", "scheme": "midpoint", "DT1": 8e-4, "T": 0.02, "vx0": 300.0,
         "v0": -1000.0, "mu": 0.3, "levels": [1, 2, 3, 4, 5], "ranks": [1, 2]}
#: the two cases of every (level, ranks): simulate()'s friction keywords
CASES = {"coulomb": {"friction": "coulomb", "friction_options": {"mu": SUITE["mu"]}}, "none": {}}
#: the timings that are medians over the repetitions
MEDIAN_KEYS = ("mesh_time", "setup_time", "step_time_free", "step_time_contact", "step_time_contact_mean",
               "first_contact_time", "wall_time", "cpu_step_free", "cpu_step_contact")
#: a case is given up after this (s): level 5 takes ~1 min
TIMEOUT = 1800.0


def level_dt(level):
    """The Table 2 time step of a level (s)."""
    return SUITE["DT1"] / 2 ** (level - 1)


def _phases(stamps, start, rows):
    """Per-step durations and the steps' records, split in free and contact steps."""
    import numpy as np
    times = np.diff(np.array([start] + stamps))
    contact = np.array([r[0] > 0 for r in rows], dtype=bool)
    its, stick, slip, lin = (np.array([r[k] for r in rows], dtype=float) for k in (1, 2, 3, 4))
    return times, contact, its, stick, slip, lin


def run_case(spec, comm=None):
    """One run of ``spec`` (level, case, ranks) on ``comm``; the record (the same on every rank).

    Adds to ``spec``: dofs, N_g, dt, steps, mesh_time, setup_time, steps_free, steps_contact,
    first_contact_step, step_time_free, step_time_contact (medians over the phase's steps, s),
    step_time_contact_mean, first_contact_time, cpu_step_free and cpu_step_contact (medians of
    rank 0's CPU time per step: less sensitive to other jobs than the wall time),
    newton_per_step, newton_contact_mean, newton_contact_max, stick_contact_mean/max,
    slip_contact_mean/max, steps_with_slip, solves_per_step, wall_time, peak_rss_mb and
    cpu_time (per rank), status.
    """
    from mpi4py import MPI
    import numpy as np
    from sdm_dolfinx import disc, simulate
    comm = comm or MPI.COMM_WORLD
    rec = dict(spec, ranks=comm.size, dt=level_dt(spec["level"]))
    comm.Barrier()
    t0 = time.perf_counter()
    problem = disc.problem(level=spec["level"], vx0=SUITE["vx0"], v0=SUITE["v0"], comm=comm)
    comm.Barrier()
    rec["mesh_time"] = time.perf_counter() - t0
    stamps, cpu, rows, state = [], [], [], {"lin": 0}

    def on_step(n, row):
        stamps.append(time.perf_counter())
        cpu.append(time.process_time())
        rows.append((row["n_active"], row["newton_its"], row.get("n_stick", 0), row.get("n_slip", 0),
                     row["linear_its_total"] - state["lin"]))
        state["lin"] = row["linear_its_total"]

    comm.Barrier()
    t1 = time.perf_counter()
    c1 = time.process_time()
    try:
        result = simulate(problem, pair=SUITE["pair"], scheme=SUITE["scheme"], dt=rec["dt"], T=SUITE["T"],
                          on_step=on_step, **CASES[spec["case"]])
    except Exception as e:
        return dict(rec, status="failed", error=str(e).splitlines()[0][:300], steps_done=len(stamps))
    rec["wall_time"] = time.perf_counter() - t1
    info = result.info
    rec.update(status="finished", dofs=info["dim_W"], N_g=info["N_g"], setup_time=info["setup_time"],
               steps=info["steps"])
    times, contact, its, stick, slip, lin = _phases(stamps, t1 + info["setup_time"], rows)
    # CPU time of this rank per step (set-up's CPU time in step 1's: excluded below with it)
    ctimes = np.diff(np.array([c1] + cpu))
    first = int(np.argmax(contact)) if contact.any() else None
    later = contact.copy()
    if first is not None:
        later[first] = False
    med = lambda a: float(np.median(a)) if a.size else None
    mean = lambda a: float(a.mean()) if a.size else None
    top = lambda a: int(a.max()) if a.size else None
    rec.update(steps_free=int((~contact).sum()), steps_contact=int(contact.sum()),
               first_contact_step=None if first is None else first + 1,
               step_time_free=med(times[~contact]), step_time_contact=med(times[later]),
               step_time_contact_mean=mean(times[contact]),
               cpu_step_free=med(ctimes[1:][~contact[1:]]), cpu_step_contact=med(ctimes[later]),
               first_contact_time=None if first is None else float(times[first]),
               newton_per_step=mean(its), newton_contact_mean=mean(its[contact]), newton_contact_max=top(its[contact]),
               stick_contact_mean=mean(stick[contact]), stick_contact_max=top(stick[contact]),
               slip_contact_mean=mean(slip[contact]), slip_contact_max=top(slip[contact]),
               steps_with_slip=int((slip > 0).sum()), solves_per_step=mean(lin), max_active=top(np.array(
                   [r[0] for r in rows])))
    del result
    import gc
    gc.collect()
    comm.Barrier()
    rec["peak_rss_mb"] = comm.allgather(round(BR.peak_rss_mb(), 1))
    rec["cpu_time"] = comm.allgather(round(time.process_time(), 2))
    return rec


def combine(recs):
    """Medians of the timings over the repetitions; memory: the largest; the rest from run 1."""
    out = dict(recs[0], repeats=len(recs))
    for k in MEDIAN_KEYS:
        vals = [r[k] for r in recs if r.get(k) is not None]
        out[k] = statistics.median(vals) if vals else None
    if all("peak_rss_mb" in r for r in recs):
        out["peak_rss_mb"] = [max(v) for v in zip(*[r["peak_rss_mb"] for r in recs])]
    out["load_before"] = [r.get("load_before") for r in recs]
    out["load_after"] = [r.get("load_after") for r in recs]
    return out


def spawn(spec, ranks, timeout=TIMEOUT, nice=0):
    """One case in a fresh process of this script (:func:`bench.run.spawn`: ``mpirun -n ranks``
    when ranks > 1, the same MPI environment); ``nice``: its niceness increment."""
    return BR.spawn(spec, ranks, timeout, script=Path(__file__).resolve(), nice=nice)


def ratios(records):
    """Per (level, ranks) with both cases finished: friction / frictionless of the median time
    per contact step (``contact``), of its mean (``contact_mean``, the first contact step in)
    and of the median free step (``free``)."""
    by = {(r["level"], r["ranks"], r["case"]): r for r in records if r.get("status") == "finished"}
    out = []
    for (level, ranks, case), c in sorted(by.items()):
        n = by.get((level, ranks, "none"))
        if case != "coulomb" or n is None:
            continue
        q = lambda k: c[k] / n[k] if c.get(k) and n.get(k) else None
        out.append({"level": level, "ranks": ranks, "contact": q("step_time_contact"),
                    "cpu_contact": q("cpu_step_contact"),
                    "contact_mean": q("step_time_contact_mean"), "free": q("step_time_free"),
                    "setup": q("setup_time"), "wall": q("wall_time")})
    return out


def uptime():
    """The output of ``uptime`` (the machine's load, for the record)."""
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())


def run_pair(level, ranks, repeat, short, nice):
    """The cases of one (level, ranks), alternated (coulomb, none, coulomb, none, ...) so that
    both see the same load, repeated while every run is shorter than ``short`` s; the
    combined records."""
    recs = {case: [] for case in CASES}
    for _ in range(repeat):
        for case in CASES:
            recs[case].append(spawn({"problem": "disc", "level": level, "case": case}, ranks, nice=nice))
        if any(v[-1].get("status") != "finished" or v[-1].get("wall_time", 1e9) > short for v in recs.values()):
            break
    return [combine(v) for v in recs.values()]


def run_suite(levels, ranks_list, out, repeat, short, nice, log=print):
    """Every case; writes ``out/disc_friction.json`` after each (level, ranks) (the results
    so far). A case run again replaces its record, which moves to ``superseded``."""
    path = out / "disc_friction.json"
    data = json.loads(path.read_text()) if path.exists() else {}
    records, superseded = data.get("records", []), data.get("superseded", [])
    runs = data.get("uptime", []) + [{"start": uptime(), "levels": levels, "ranks": ranks_list}]
    key = lambda r: (r["level"], r["ranks"], r["case"])
    for ranks in ranks_list:
        for level in levels:
            for rec in run_pair(level, ranks, repeat, short, nice):
                superseded += [x for x in records if key(x) == key(rec)]
                records = [x for x in records if key(x) != key(rec)] + [rec]
                log(line(rec))
            runs[-1]["end"] = uptime()
            data = {"suite": "disc-friction", "parameters": SUITE, "environment": BR.environment(),
                    "uptime": runs, "records": records, "ratios": ratios(records), "superseded": superseded}
            path.write_text(json.dumps(data, indent=1))
    return data


def _ms(x):
    return "-" if x is None else f"{1e3 * x:.1f}"


def line(r):
    """One log line of a record."""
    return (f"level {r['level']} {r['case']:8s} ranks {r['ranks']}: {r['status']:8s} "
            f"setup {BR._f(r.get('setup_time'))} s, free {_ms(r.get('step_time_free'))} ms, "
            f"contact {_ms(r.get('step_time_contact'))} ms (first {_ms(r.get('first_contact_time'))}), "
            f"Newton contact {BR._f(r.get('newton_contact_mean'))} max {r.get('newton_contact_max')}, "
            f"slip max {r.get('slip_contact_max')}, rss {r.get('peak_rss_mb')} "
            f"(x{r['repeats']}, load {r['load_before']}) {r.get('error', '')}")


def _row(r, ratio):
    """One markdown row of a record; ``ratio``: the friction / frictionless contact ratio or "-"."""
    fr = r["case"] == "coulomb"
    ss = (f"{BR._f(r.get('stick_contact_mean'), 1)} ({r.get('stick_contact_max')}) / "
          f"{BR._f(r.get('slip_contact_mean'), 1)} ({r.get('slip_contact_max')}); {r.get('steps_with_slip')}"
          if fr else "-")
    cells = [r["level"], r.get("dofs", "-"), f"{r['dt']:.1e}", r["ranks"], r["case"], BR._f(r.get("setup_time"), 1),
             _ms(r.get("step_time_free")), _ms(r.get("step_time_contact")), _ms(r.get("step_time_contact_mean")),
             _ms(r.get("first_contact_time")), _ms(r.get("cpu_step_contact")), BR._f(r.get("newton_per_step")),
             f"{BR._f(r.get('newton_contact_mean'))} / {r.get('newton_contact_max')}", ss,
             BR._f(r.get("solves_per_step")), f"{max(r.get('peak_rss_mb') or [0]):.0f}", ratio,
             r.get("load_before"), r["status"]]
    return "| " + " | ".join(str(c) for c in cells) + " |"


def table(data):
    """The records as a markdown table (times in ms), with the contact ratio on the Coulomb rows."""
    rat = {(q["level"], q["ranks"]): q for q in data.get("ratios", [])}
    head = ["level", "dofs", "dt s", "ranks", "friction", "setup s", "free ms/step", "contact ms/step",
            "contact mean ms", "first contact ms", "contact CPU ms/step", "Newton/step", "Newton in contact mean / max",
            "stick / slip in contact: mean (max); steps with slip", "solves/step", "peak RSS MiB/rank",
            "contact ratio wall (CPU)", "load", "status"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in sorted(data["records"], key=lambda r: (r["level"], r["ranks"], r["case"] != "none")):
        q = rat.get((r["level"], r["ranks"])) if r["case"] == "coulomb" else None
        lines.append(_row(r, "-" if q is None else f"{BR._f(q['contact'])} ({BR._f(q.get('cpu_contact'))})"))
    return "\n".join(lines)


def plot(data, png):
    """Median time per contact and free step against dofs (left), the ratio (right)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 5))
    recs = [r for r in data["records"] if r.get("status") == "finished"]
    for case in CASES:
        for ranks in sorted({r["ranks"] for r in recs}):
            rs = sorted((r for r in recs if r["case"] == case and r["ranks"] == ranks), key=lambda r: r["dofs"])
            style = dict(color="C0" if case == "coulomb" else "C3", ls="-" if ranks == 1 else "--",
                         marker="o" if ranks == 1 else "s")
            ax.loglog([r["dofs"] for r in rs], [r["step_time_contact"] for r in rs], **style,
                      label=f"{case}, contact, {ranks} rank(s)")
            ax.loglog([r["dofs"] for r in rs], [r["step_time_free"] for r in rs], **style, alpha=0.3,
                      label=f"{case}, free, {ranks} rank(s)")
    ax.set(xlabel="dofs (dim W^h)", ylabel="median time per step (s)",
           title="disc P2/P1, Table 2 dt, vx0 = 300 mm/s, Coulomb mu = 0.3")
    dofs = {r["level"]: r["dofs"] for r in recs}
    for ranks in sorted({q["ranks"] for q in data.get("ratios", [])}):
        qs = [q for q in data["ratios"] if q["ranks"] == ranks and q["contact"]]
        bx.semilogx([dofs[q["level"]] for q in qs], [q["contact"] for q in qs], "o-" if ranks == 1 else "s--",
                    label=f"{ranks} rank(s)")
    bx.axhline(2.0, color="r", lw=0.8, label="target (level 5)")
    bx.set(xlabel="dofs (dim W^h)", ylabel="friction / frictionless, median contact step", ylim=(0, None))
    for a in (ax, bx):
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=SUITE["levels"], help="disc levels (default 1-5)")
    ap.add_argument("--ranks", type=int, nargs="+", default=SUITE["ranks"], help="rank counts (default 1 2)")
    ap.add_argument("--repeat", type=int, default=3, help="repetitions of short runs (default 3)")
    ap.add_argument("--short", type=float, default=30.0, help="a run shorter than this (s) is repeated")
    ap.add_argument("--nice", type=int, default=0, help="niceness increment of the runs (default 0)")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="results folder")
    ap.add_argument("--png", type=Path, default=None, help="plot (default bench/friction_time_per_step.png)")
    ap.add_argument("--table", action="store_true", help="print the markdown table and stop")
    ap.add_argument("--plot-only", action="store_true")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--result", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        rec = run_case(json.loads(args.worker))
        if BR._rank() == 0:
            Path(args.result).write_text(json.dumps(rec))
        return 0
    path = args.out / "disc_friction.json"
    if args.table:
        print(table(json.loads(path.read_text())))
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    if not args.plot_only:
        run_suite(args.levels, args.ranks, args.out, args.repeat, args.short, args.nice)
    png = args.png or (HERE / "friction_time_per_step.png" if args.out.resolve() == (HERE / "results").resolve()
                       else args.out / "friction_time_per_step.png")
    plot(json.loads(path.read_text()), png)
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
