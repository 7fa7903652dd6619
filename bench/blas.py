"""Which BLAS: Debian's reference (netlib) against OpenBLAS (serial), measured on our own runs.

Each case runs twice in fresh processes, once with each library forced through
``LD_LIBRARY_PATH`` (both packages installed; the loader takes the ``libblas.so.3`` and
``liblapack.so.3`` of the first folder it finds, whatever the ``update-alternatives`` link
says), and records: the set-up time (mesh, assembly and the factorisation of the step
matrix, whose dense frontal updates are BLAS 3), the mean time per step, the final
displacement and the energy and contact-force histories. The two runs of a case must agree
to round-off (relative 1e-9 on the displacement and histories, far below any tolerance of the
tests) and neither may crash; then the ratio of their times is the gain.

    .venv/bin/python bench/blas.py                  # the recorded cases -> bench/results/blas.json
    .venv/bin/python bench/blas.py --cases ball:2   # one case

A case is ``problem:level[:ranks]`` (disc or ball; the disc runs 80 steps of 5e-5 s from 0.02 mm
above the foundation, the ball 40 steps of 4e-5 s from 0.1 mm above the plane: both contact
and flight steps).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
LIB = Path("/usr/lib/x86_64-linux-gnu")
#: the folders that hold each library's libblas.so.3 and liblapack.so.3
LIBRARIES = {"reference": [LIB / "blas", LIB / "lapack"], "openblas": [LIB / "openblas-serial"]}
CASES = {"disc": {"dt": 5e-5, "T": 4e-3, "height": 0.02}, "ball": {"dt": 4e-5, "T": 1.6e-3, "height": 0.1}}
DEFAULT = ["disc:4", "ball:2", "ball:3", "ball:3:2"]
#: relative agreement required of the two libraries' results (round-off of a different summation order)
AGREE = 1e-9


def worker(case, out):
    """Run ``case`` in this process (its ranks) and save its numbers to ``out`` (rank 0)."""
    import numpy as np
    from mpi4py import MPI
    from sdm_dolfinx import simulate
    from sdm_dolfinx.mpiutil import gather_rows
    from sdm_dolfinx.problems import ball, disc
    name, level = case["problem"], case["level"]
    prm = CASES[name]
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    problem = {"disc": disc, "ball": ball}[name].problem(comm, level=level, height=prm["height"])
    t_mesh = time.perf_counter() - t0
    stamps = []
    r = simulate(problem, pair="P2/P1", dt=prm["dt"], T=prm["T"], on_step=lambda n, row: stamps.append(
        time.perf_counter()))
    U = r.displacement()
    imap = U.function_space.dofmap.index_map
    n = imap.size_local * U.function_space.dofmap.index_map_bs
    x = np.asarray(U.function_space.tabulate_dof_coordinates()[:imap.size_local])
    u = U.x.array[:n].reshape(-1, U.function_space.dofmap.index_map_bs)
    rows = gather_rows(np.hstack([x, u]), comm)        # sorted by coordinates: rank-independent order
    if comm.rank == 0:
        rows = rows[np.lexsort(np.round(rows[:, :3], 9).T[::-1])]
        steps = np.diff(np.array(stamps))
        json_out = {"mesh_time": t_mesh, "setup_time": r.info["setup_time"], "step_time": float(np.mean(steps)),
                    "steps": len(stamps), "dofs": r.info["dim_W"], "ranks": comm.size,
                    "energy": np.asarray(r.timeseries["energy"]).tolist(),
                    "force": np.asarray(r.timeseries["contact_force"]).tolist(), "u": rows[:, 3:].ravel().tolist(),
                    "blas": os.path.realpath(_loaded("libblas"))}
        Path(out).write_text(json.dumps(json_out))


def _loaded(stem):
    """The file of the shared library ``stem`` this process has mapped."""
    for line in Path("/proc/self/maps").read_text().splitlines():
        if stem in line and "/" in line:
            return line.split()[-1]
    return "?"


def spawn(case, library, timeout=3600):
    """One run of ``case`` under ``library`` in a fresh process (mpirun for ranks > 1)."""
    env = dict(os.environ, LD_LIBRARY_PATH=":".join(str(p) for p in LIBRARIES[library]),
               OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_btl="self,vader",
               OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_mpi_yield_when_idle="1")
    with tempfile.TemporaryDirectory() as tmp:
        res = Path(tmp) / "r.json"
        cmd = [sys.executable, __file__, "--worker", json.dumps(case), "--result", str(res)]
        if case["ranks"] > 1:
            cmd = ["mpirun", "-x", "LD_LIBRARY_PATH", "-n", str(case["ranks"])] + cmd
        load = os.getloadavg()[0]
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
        if not res.exists():
            return {"status": "crashed", "returncode": p.returncode, "error": (p.stderr or p.stdout)[-600:]}
        return {**json.loads(res.read_text()), "status": "finished", "load_before": round(load, 2)}


def compare(a, b):
    """Largest relative differences of the two runs' results."""
    import numpy as np
    rel = lambda x, y: float(np.max(np.abs(np.subtract(x, y))) / max(np.max(np.abs(x)), 1e-300))
    return {k: rel(a[k], b[k]) for k in ("u", "energy", "force")}


def parse_case(text):
    parts = text.split(":")
    if parts[0] not in CASES or len(parts) not in (2, 3):
        raise argparse.ArgumentTypeError(f"{text!r}: a case is problem:level[:ranks], problem one of {list(CASES)}")
    return {"problem": parts[0], "level": int(parts[1]), "ranks": int(parts[2]) if len(parts) == 3 else 1}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", type=parse_case, default=[parse_case(c) for c in DEFAULT])
    ap.add_argument("--out", type=Path, default=HERE / "results" / "blas.json")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--result", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        worker(json.loads(args.worker), args.result)
        return 0
    missing = [str(p) for ps in LIBRARIES.values() for p in ps if not (p / "libblas.so.3").exists()
               and not (p / "liblapack.so.3").exists()]
    if missing:
        print(f"blas.py: missing {', '.join(missing)} (apt-get install libblas3 liblapack3 libopenblas0-serial)")
        return 2
    records = []
    for case in args.cases:
        runs = {lib: spawn(case, lib) for lib in LIBRARIES}
        rec = {**case, **{lib: {k: v for k, v in r.items() if k not in ("u", "energy", "force")}
                          for lib, r in runs.items()}}
        if all(r["status"] == "finished" for r in runs.values()):
            rec["difference"] = compare(runs["reference"], runs["openblas"])
            rec["agree"] = all(v <= AGREE for v in rec["difference"].values())
            rec["setup_gain"] = runs["reference"]["setup_time"] / runs["openblas"]["setup_time"]
            rec["step_gain"] = runs["reference"]["step_time"] / runs["openblas"]["step_time"]
            print(f"{case['problem']} level {case['level']} ({runs['reference']['dofs']} dofs), {case['ranks']} "
                  f"rank(s): set-up {runs['reference']['setup_time']:.1f} -> {runs['openblas']['setup_time']:.1f} s "
                  f"(x{rec['setup_gain']:.2f}), step {1e3 * runs['reference']['step_time']:.0f} -> "
                  f"{1e3 * runs['openblas']['step_time']:.0f} ms (x{rec['step_gain']:.2f}); "
                  f"largest relative difference {max(rec['difference'].values()):.1e}", flush=True)
        else:
            print(f"{case}: " + ", ".join(f"{lib} {r['status']}" for lib, r in runs.items()), flush=True)
        records.append(rec)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"records": records, "date": time.strftime("%Y-%m-%d %H:%M:%S"),
                                        "cpu": _cpu()}, indent=1))
    return 0


def _cpu():
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return "?"


if __name__ == "__main__":
    sys.path.insert(0, str(HERE.parent))
    sys.exit(main())
