"""Benchmark of the step solvers: time per step against dofs, membrane and disc, 1 and 2 ranks.

For every case (problem, size, strategy, ranks) a fresh process (``mpirun -n R`` for R > 1)
runs :func:`sdm_dolfinx.simulate` and records: the set-up time (mesh generation separately),
the mean time per step in the free phase (no vertex in contact after the step) and in the
impact phase, Newton iterations and linear solves per step (a Krylov iteration or one
solve with a factorisation each), and the peak resident memory of every rank. Short runs
are repeated and each figure is the median over the repetitions. The load average of the
machine is recorded before and after each run (timings taken under load are inflated).

    python bench/run.py                         # the full suite (hours)
    python bench/run.py --suite disc --ranks 1  # a part of it
    python bench/run.py --quick --out /tmp/b    # tiny sizes, seconds (the test suite runs this)
    python bench/run.py --plot-only             # redraw bench/time_per_step.png from the JSON

Results go to ``bench/results/<suite>.json`` (one record per case, see :func:`run_case`)
and the plot to ``bench/time_per_step.png``.
"""
import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

#: strategy name -> simulate() keywords
STRATEGIES = {
    "auto": {"vi_solver": "ssn", "linear": "auto"},
    "schur": {"vi_solver": "ssn", "linear": "schur"},
    "cg-factor": {"vi_solver": "ssn", "linear": "cg-factor"},
    "cg-amg": {"vi_solver": "ssn", "linear": "cg-amg"},
    "cg-gamg": {"vi_solver": "ssn", "linear": "cg-gamg"},
    "cg-pmg": {"vi_solver": "ssn", "linear": "cg-pmg"},
    "amg": {"vi_solver": "ssn", "linear": "amg"},
    "lu": {"vi_solver": "ssn", "linear": "lu"},
    "rsls": {"vi_solver": "vinewtonrsls", "linear": "lu"},
}

#: the suites: problem parameters, sizes, and the largest size each strategy runs at (the
#: baselines refactorise at every Newton iteration and would take hours beyond)
SUITES = {
    "membrane": {"problem": "membrane", "pair": "P1+/P0", "dt": 1e-3, "T": 0.4,
                 "sizes": [20, 40, 80, 160, 320],
                 "max_size": {"lu": 80, "rsls": 80, "schur": 80, "cg-factor": 160, "amg": 160, "cg-amg": 160,
                              "cg-pmg": 0}},       # cg-pmg coarsens P2: the membrane's P1+ has none
    "disc": {"problem": "disc", "pair": "P2/P1", "dt": 5e-5, "T": 0.02,
             "sizes": [1, 2, 3, 4, 5],
             "max_size": {"lu": 2, "rsls": 2, "amg": 3, "cg-amg": 3, "schur": 4, "cg-factor": 4}},
    # level 5 over 3 steps with the disc 0.02 mm above the foundation: contact from the
    # first step, so the baselines' time per impact step at ~127k dofs in minutes
    "disc-window": {"problem": "disc", "pair": "P2/P1", "dt": 5e-5, "T": 1.5e-4, "height": 0.02,
                    "sizes": [5], "max_size": {}},
    "disc-level6": {"problem": "disc", "pair": "P2/P1", "dt": 2.5e-5, "T": 0.02, "sizes": [6],
                    "max_size": {}},
    # the 3-D ball: 25 steps of flight from 0.1 mm, then 50 of contact up to about the
    # maximal compression (Hertz: t_c = 3.9 ms, so the contact steps are the loaded half)
    "ball": {"problem": "ball", "pair": "P2/P1", "dt": 4e-5, "T": 3e-3, "height": 0.1,
             "sizes": [1, 2, 3, 4, 5],
             "max_size": {"lu": 1, "rsls": 1, "amg": 2, "cg-amg": 2, "cg-factor": 2, "cg-gamg": 2, "cg-pmg": 3}},
    # the ball where 75 steps would take hours (cg-gamg; auto's choice at level 5 on this machine):
    # 6 steps from 4 um above the plane, contact from step 2 (up to 25 / 41 / 90 active vertices
    # at levels 3 / 4 / 5)
    "ball-window": {"problem": "ball", "pair": "P2/P1", "dt": 4e-5, "T": 2.4e-4, "height": 0.004,
                    "sizes": [3, 4, 5, 6],
                    "max_size": {"lu": 1, "rsls": 1, "amg": 2, "cg-amg": 2, "cg-factor": 2, "schur": 4, "auto": 4, "cg-gamg": 5}},
}

QUICK = {
    "membrane": {"problem": "membrane", "pair": "P1+/P0", "dt": 2e-3, "T": 0.4, "sizes": [4, 8], "max_size": {}},
    "disc": {"problem": "disc", "pair": "P2/P1", "dt": 2e-4, "T": 0.014, "sizes": [1], "max_size": {}},
    "ball": {"problem": "ball", "pair": "P2/P1", "dt": 4e-5, "T": 2.4e-4, "height": 0.004, "sizes": [1],
             "max_size": {}},
}


def make_problem(spec, comm):
    if spec["problem"] == "membrane":
        from sdm_dolfinx import membrane
        return membrane.problem(N=spec["size"], comm=comm)
    from sdm_dolfinx.problems import ball, disc
    extra = {"height": spec["height"]} if "height" in spec else {}
    return {"disc": disc, "ball": ball}[spec["problem"]].problem(level=spec["size"], comm=comm, **extra)


def peak_rss_mb():
    """Peak resident memory of this process (MiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_case(spec, comm=None):
    """One run of ``spec`` on ``comm``; the record (same on every rank).

    ``spec``: problem, size, pair, dt, T, strategy (a key of :data:`STRATEGIES`), optional
    height (disc). The record adds: dofs (dim W^h), dim_H, N_g, ranks, mesh_time, setup_time,
    steps, steps_free, steps_impact, step_time_free, step_time_impact, step_time (mean over
    all steps, s), newton_per_step, linear_per_step, linear_per_step_impact, max_active,
    wall_time, peak_rss_mb (per rank), status.
    """
    from mpi4py import MPI
    import numpy as np
    from sdm_dolfinx import simulate
    comm = comm or MPI.COMM_WORLD
    rec = dict(spec, ranks=comm.size)
    comm.Barrier()
    t0 = time.perf_counter()
    problem = make_problem(spec, comm)
    comm.Barrier()
    rec["mesh_time"] = time.perf_counter() - t0
    stamps, impact, its, lin = [], [], [], []
    state = {"lin": 0}

    def on_step(n, row):
        stamps.append(time.perf_counter())
        impact.append(row["n_active"] > 0)
        its.append(row["newton_its"])
        lin.append(row["linear_its_total"] - state["lin"])
        state["lin"] = row["linear_its_total"]

    kw = dict(STRATEGIES[spec["strategy"]])
    comm.Barrier()
    t1 = time.perf_counter()
    try:
        result = simulate(problem, pair=spec["pair"], dt=spec["dt"], T=spec["T"], on_step=on_step, **kw)
        rec["status"] = "finished"
        # step 1 is timed from the end of simulate's set-up (the row of t = 0 is in it)
        starts = [t1 + result.info["setup_time"]] + stamps[:-1]
    except Exception as e:          # a failing strategy (RSLS cycling) is a result too
        result = None
        rec["status"] = "failed"
        rec["error"] = str(e).splitlines()[0][:300]
        starts = [None] + stamps[:-1]
    times = [b - a for a, b in zip(starts, stamps) if a is not None]
    if len(times) < len(stamps):
        impact, its, lin = impact[1:], its[1:], lin[1:]
    rec["wall_time"] = time.perf_counter() - t1
    if result is not None:
        info = result.info
        rec.update(dofs=info["dim_W"], dim_H=info["dim_H"], N_g=info["N_g"], setup_time=info["setup_time"],
                   steps=info["steps"])
        rec["max_active"] = int(np.max(result.timeseries["n_active"]))
        rec["linear_strategy"] = info.get("linear_strategy")      # what auto chose
        del result
    rec["blas"] = os.path.realpath("/usr/lib/x86_64-linux-gnu/libblas.so.3")
    times, impact = np.array(times), np.array(impact, dtype=bool)
    its, lin = np.array(its, dtype=float), np.array(lin, dtype=float)
    mean = lambda a: float(a.mean()) if a.size else None
    rec.update(steps_done=int(times.size), steps_free=int((~impact).sum()), steps_impact=int(impact.sum()),
               step_time=mean(times), step_time_free=mean(times[~impact]), step_time_impact=mean(times[impact]),
               newton_per_step=mean(its), linear_per_step=mean(lin), linear_per_step_impact=mean(lin[impact]))
    import gc
    gc.collect()
    comm.Barrier()
    rec["peak_rss_mb"] = comm.allgather(round(peak_rss_mb(), 1))
    rec["cpu_time"] = comm.allgather(round(time.process_time(), 2))     # per rank, whole process
    return rec


MEDIAN_KEYS = ("mesh_time", "setup_time", "step_time", "step_time_free", "step_time_impact", "wall_time")


def combine(recs):
    """Median over repetitions of the timings; memory: the largest; the rest from run 1."""
    out = dict(recs[0])
    out["repeats"] = len(recs)
    for k in MEDIAN_KEYS:
        vals = [r[k] for r in recs if r.get(k) is not None]
        out[k] = statistics.median(vals) if vals else None
    out["peak_rss_mb"] = [max(v) for v in zip(*[r["peak_rss_mb"] for r in recs])]
    out["load_before"] = [r.get("load_before") for r in recs]
    out["load_after"] = [r.get("load_after") for r in recs]
    return out


def spawn(spec, ranks, timeout, script=None, nice=0):
    """Run one case in a fresh process (``mpirun -n ranks`` when ranks > 1): ``script --worker
    SPEC --result FILE`` (default this file; bench/friction_run.py passes its own), with the
    niceness increment ``nice``."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_btl="self,vader", OMPI_MCA_mpi_yield_when_idle="1", OMPI_MCA_rmaps_base_oversubscribe="1")
    with tempfile.TemporaryDirectory() as tmp:
        res = Path(tmp) / "rec.json"
        cmd = [sys.executable, str(script or Path(__file__).resolve()), "--worker", json.dumps(spec), "--result",
               str(res)]
        if ranks > 1:
            cmd = ["mpirun", "-n", str(ranks)] + cmd
        if nice:
            cmd = ["nice", "-n", str(nice)] + cmd
        load0 = os.getloadavg()[0]
        try:
            p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
            if res.exists():
                rec = json.loads(res.read_text())
            else:
                rec = dict(spec, ranks=ranks, status="crashed", error=(p.stderr or p.stdout)[-500:])
        except subprocess.TimeoutExpired:
            rec = dict(spec, ranks=ranks, status="timeout", error=f"no result within {timeout} s")
        rec["load_before"], rec["load_after"] = round(load0, 2), round(os.getloadavg()[0], 2)
        return rec


def environment():
    import numpy as np
    from sdm_dolfinx import compat
    return {"host": platform.node(), "cpus": os.cpu_count(), "python": platform.python_version(),
            "numpy": np.__version__, "versions": compat.versions(),
            "blas": os.path.realpath("/usr/lib/x86_64-linux-gnu/libblas.so.3"),
            "date": time.strftime("%Y-%m-%d %H:%M:%S")}


def run_suite(name, suite, strategies, ranks_list, out, repeat, short, timeout, inprocess=False, log=print,
              skip_done=False):
    """Every case of one suite; writes ``out/<name>.json`` after each case (results so far)."""
    path = out / f"{name}.json"
    data = json.loads(path.read_text()) if path.exists() and not inprocess else {}
    records = data.get("records", [])
    key = lambda r: (r["problem"], r["size"], r["strategy"], r["ranks"], r.get("height"))
    for ranks in ranks_list:
        for size in suite["sizes"]:
            for strat in strategies:
                if size > suite["max_size"].get(strat, float("inf")):
                    log(f"{name:12s} size {size:>4} {strat:10s} ranks {ranks}: skipped (this suite runs it up to "
                        f"size {suite['max_size'][strat]})")
                    continue
                spec = {k: suite[k] for k in ("problem", "pair", "dt", "T") if k in suite}
                if "height" in suite:
                    spec["height"] = suite["height"]
                spec.update(size=size, strategy=strat)
                if skip_done and any(key(x) == key(dict(spec, ranks=ranks)) and x["status"] == "finished"
                                     for x in records):
                    continue
                recs = []
                while True:
                    if inprocess:
                        load0 = os.getloadavg()[0]
                        r = run_case(spec)
                        r["load_before"], r["load_after"] = round(load0, 2), round(os.getloadavg()[0], 2)
                    else:
                        r = spawn(spec, ranks, timeout)
                    recs.append(r)
                    if r.get("status") != "finished" or len(recs) >= repeat or r.get("wall_time", 1e9) > short:
                        break
                rec = combine(recs)
                records = [x for x in records if key(x) != key(rec)] + [rec]
                log(f"{name:12s} size {size:>4} {strat:10s} ranks {ranks}: {rec['status']:8s} "
                    f"setup {_f(rec.get('setup_time'))} s, step free {_f(rec.get('step_time_free'), 4)} s, "
                    f"impact {_f(rec.get('step_time_impact'), 4)} s, newton/step {_f(rec.get('newton_per_step'))}, "
                    f"solves/step {_f(rec.get('linear_per_step'))}, rss {rec.get('peak_rss_mb')} MiB "
                    f"(x{rec['repeats']}, load {rec['load_before']})")
                data = {"suite": name, "parameters": {k: v for k, v in suite.items() if k != "max_size"},
                        "environment": environment(), "records": records}
                if not inprocess or _rank() == 0:
                    path.write_text(json.dumps(data, indent=1))
    return data


def _rank():
    from mpi4py import MPI
    return MPI.COMM_WORLD.rank


def _f(x, nd=2):
    return "-" if x is None else f"{x:.{nd}f}"


def slope(dofs, times):
    """Least-squares slope of log(time) against log(dofs)."""
    import numpy as np
    return float(np.polyfit(np.log(dofs), np.log(times), 1)[0])


TITLES = {"membrane": "membrane P1+/P0, dt = 1e-3, 400 steps", "disc": "disc P2/P1, dt = 5e-5, 400 steps",
          "ball": "ball (3-D) P2/P1, dt = 4e-5, 75 steps",
          "ball-window": "ball (3-D) P2/P1, 6 steps from first contact"}


def _lines(out, name):
    """The finished records of ``out/<name>.json`` as plot lines: (strategy, ranks, records by dofs)."""
    recs = [r for r in json.loads((out / f"{name}.json").read_text())["records"] if r.get("status") == "finished"]
    for strat, ranks in sorted({(r["strategy"], r["ranks"]) for r in recs}):
        yield strat, ranks, sorted((r for r in recs if r["strategy"] == strat and r["ranks"] == ranks),
                                   key=lambda r: r["dofs"])


def _panel(ax, title, ylabel):
    ax.set_xlabel("dofs (dim W^h)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)


def plot(out, png):
    """Log-log time per step against dofs, one line per (problem, strategy, ranks); for the ball
    (when recorded) also the peak memory per rank."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = [n for n in TITLES if (out / f"{n}.json").exists()]
    if not names:
        return                      # nothing recorded in out (every case skipped)
    balls = [n for n in names if n.startswith("ball")]
    panels = len(names) + bool(balls)
    cols = min(panels, 3)
    fig, axes = plt.subplots(-(-panels // cols), cols, figsize=(6 * cols, 5 * -(-panels // cols)), squeeze=False)
    axes = list(axes.flat)
    for ax in axes[panels:]:
        ax.set_visible(False)
    ranks_label = lambda ranks: f"{ranks} rank{'s' if ranks > 1 else ''}"       # noqa: E731
    for ax, name in zip(axes, names):
        for strat, ranks, rs in _lines(out, name):
            ax.loglog([r["dofs"] for r in rs], [r["step_time"] for r in rs], "o-" if ranks == 1 else "s--",
                      label=f"{strat}, {ranks_label(ranks)}")
        _panel(ax, TITLES[name], "mean time per step (s)")
    if balls:
        ax = axes[panels - 1]
        for name in balls:
            for strat, ranks, rs in _lines(out, name):
                ax.loglog([r["dofs"] for r in rs], [max(r["peak_rss_mb"]) / 1024 for r in rs],
                          "o-" if ranks == 1 else "s--", label=f"{name}: {strat}, {ranks_label(ranks)}")
        _panel(ax, "ball (3-D): memory per rank", "peak resident memory of the largest rank (GiB)")
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)


def table(out, names):
    """The results as a markdown table (time per step in ms)."""
    ms = lambda x: "-" if x is None else f"{1e3 * x:.1f}"
    lines = ["| suite | size | dofs | strategy | ranks | setup s | free ms/step | impact ms/step | mean ms/step | "
             "Newton/step | solves/step | peak RSS MiB/rank | load | status |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name in names:
        path = out / f"{name}.json"
        if not path.exists():
            continue
        recs = json.loads(path.read_text())["records"]
        order = list(STRATEGIES)
        for r in sorted(recs, key=lambda r: (r["size"], r["ranks"], order.index(r["strategy"]))):
            lines.append(f"| {name} | {r['size']} | {r.get('dofs', '-')} | {r['strategy']} | {r['ranks']} | "
                         f"{_f(r.get('setup_time'), 1)} | {ms(r.get('step_time_free'))} | "
                         f"{ms(r.get('step_time_impact'))} | {ms(r.get('step_time'))} | "
                         f"{_f(r.get('newton_per_step'))} | {_f(r.get('linear_per_step'))} | "
                         f"{max(r.get('peak_rss_mb') or [0]):.0f} | {r.get('load_before')} | {r['status']} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes (seconds): checks the script and its output")
    ap.add_argument("--suite", default=None, help=f"comma-separated suites ({', '.join(SUITES)}); "
                                                   "default membrane,disc")
    ap.add_argument("--strategies", default=None, help=f"comma-separated, of {', '.join(STRATEGIES)} (default all)")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2], help="rank counts (default 1 2)")
    ap.add_argument("--sizes", type=int, nargs="+", default=None, help="override the suite's sizes")
    ap.add_argument("--repeat", type=int, default=3, help="repetitions of short runs (default 3)")
    ap.add_argument("--short", type=float, default=30.0, help="a run shorter than this (s) is repeated")
    ap.add_argument("--timeout", type=float, default=3600.0, help="seconds before a case is given up")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="results folder")
    ap.add_argument("--png", type=Path, default=None, help="plot file (default bench/time_per_step.png)")
    ap.add_argument("--inprocess", action="store_true", help="run the cases in this process (on its ranks)")
    ap.add_argument("--plot-only", action="store_true")
    ap.add_argument("--table", action="store_true", help="print the results as a markdown table and stop")
    ap.add_argument("--skip-done", action="store_true", help="skip the cases already in the results")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--result", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        rec = run_case(json.loads(args.worker))
        if _rank() == 0:
            Path(args.result).write_text(json.dumps(rec))
        return 0
    suites = QUICK if args.quick else SUITES
    names = args.suite.split(",") if args.suite else ["membrane", "disc"]
    if args.table:
        print(table(args.out, args.suite.split(",") if args.suite else list(SUITES)))
        return 0
    strategies = args.strategies.split(",") if args.strategies else list(STRATEGIES)
    if args.quick and not args.strategies:
        strategies = ["auto", "lu"]
    out = args.out
    png = args.png or (HERE / "time_per_step.png" if out.resolve() == (HERE / "results").resolve()
                       else out / "time_per_step.png")
    if not args.inprocess or _rank() == 0:
        out.mkdir(parents=True, exist_ok=True)
    if not args.plot_only:
        log = print if (not args.inprocess or _rank() == 0) else (lambda *a: None)
        for name in names:
            suite = dict(suites[name])
            if args.sizes:
                suite["sizes"] = args.sizes
            ranks = [1] if args.inprocess else args.ranks
            run_suite(name, suite, strategies, ranks, out, 1 if args.quick else args.repeat, args.short,
                      args.timeout, inprocess=args.inprocess, log=log, skip_done=args.skip_done)
    if not args.inprocess or _rank() == 0:
        plot(out, png)
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
