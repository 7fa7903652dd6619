"""The benchmark script runs (``--quick``: tiny sizes, seconds) and writes its results in the
documented format. No timing is asserted: timings depend on the machine and its load."""
import importlib.util
import json
from pathlib import Path

import numpy as np
from mpi4py import MPI

COMM = MPI.COMM_WORLD
SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "run.py"

#: what every record of bench/results/<suite>.json holds
KEYS = {"problem", "size", "pair", "dt", "T", "strategy", "ranks", "dofs", "dim_H", "N_g", "mesh_time",
        "setup_time", "steps", "steps_free", "steps_impact", "step_time", "step_time_free",
        "step_time_impact", "newton_per_step", "linear_per_step", "peak_rss_mb", "wall_time", "status",
        "repeats", "load_before", "load_after"}


def load_bench():
    spec = importlib.util.spec_from_file_location("bench_run", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_quick_benchmark_output(mpi_tmp_path):
    bench = load_bench()
    assert bench.main(["--quick", "--inprocess", "--out", str(mpi_tmp_path)]) == 0
    COMM.Barrier()
    if COMM.rank != 0:
        return
    for suite in ("membrane", "disc"):
        data = json.loads((mpi_tmp_path / f"{suite}.json").read_text())
        assert data["suite"] == suite and "environment" in data and "parameters" in data
        recs = data["records"]
        assert {r["strategy"] for r in recs} == {"auto", "lu"}
        for r in recs:
            assert KEYS <= set(r), KEYS - set(r)
            assert r["status"] == "finished", r.get("error")
            assert r["ranks"] == COMM.size and len(r["peak_rss_mb"]) == COMM.size
            assert r["steps_free"] + r["steps_impact"] == r["steps"] > 0
            assert r["steps_impact"] > 0 and r["steps_free"] > 0      # both phases are timed
            assert r["step_time"] > 0 and r["setup_time"] > 0 and r["newton_per_step"] >= 1
            assert r["linear_per_step"] >= 1 and min(r["peak_rss_mb"]) > 0
    assert (mpi_tmp_path / "time_per_step.png").stat().st_size > 1000


def load_project():
    spec = importlib.util.spec_from_file_location("bench_project", SCRIPT.parent / "project.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_projection_recovers_a_power_law():
    """bench/project.py on synthetic curves t = a n^s: the fit returns a and s (to 1e-10), the
    ideal time is t(N)/p, a 2-rank gain g gives t(N)/g^log2(p) (capped at 2: no superlinear
    projection) and the memory per rank is memory.run_bytes(N)/p plus one process."""
    from sdm_dolfinx.solvers import memory
    proj = load_project()
    ns = [1e4, 3e4, 1e5]
    cur = {"schur": {1: [(n, 2e-8 * n ** 1.5) for n in ns], 2: [(1e5, 2e-8 * 1e5 ** 1.5 / 1.25)]},
           "cg-gamg": {1: [(n, 3e-5 * n ** 1.2) for n in ns], 2: [(1e5, 3e-5 * 1e5 ** 1.2 / 2.5)]}}
    fits, rows = proj.project(cur, 1e7, [4, 64])
    assert abs(fits["schur"]["s"] - 1.5) < 1e-10 and abs(fits["schur"]["a"] / 2e-8 - 1) < 1e-8
    assert abs(fits["cg-gamg"]["s"] - 1.2) < 1e-10 and abs(fits["schur"]["two_rank_gain"] - 1.25) < 1e-12
    for r in rows:
        a, s, g = (2e-8, 1.5, 1.25) if r["strategy"] == "schur" else (3e-5, 1.2, 2.0)
        t1 = a * 1e7 ** s
        assert abs(r["s_ideal"] / (t1 / r["ranks"]) - 1) < 1e-8
        assert abs(r["s_measured_eff"] / (t1 / g ** np.log2(r["ranks"])) - 1) < 1e-8
        need = memory.run_bytes(1e7, 3, factorised=r["strategy"] == "schur")
        assert abs(r["gb_per_rank"] - (need / r["ranks"] + memory.BYTES_PER_PROCESS) / 1e9) < 1e-9


def test_weak_scaling_model_adds_its_measured_parts():
    """bench/weak_scaling.py: on 1 rank a contact step is k w n (the local work alone); on P ranks the halo
    term is k S (alpha + h / beta) with h scaled as the surface (n_local / n_counted)^(2/3), the reductions'
    k R 2 alpha log2 P, and GAMG's levels add latency; the model's parts sum to its total."""
    spec = importlib.util.spec_from_file_location("bench_weak", SCRIPT.parent / "weak_scaling.py")
    weak = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(weak)
    counts = [{"ranks": 2, "n_local_max": 1000, "bytes_per_exchange": 8000.0, "exchanges_per_it": 20.0,
               "reductions_per_it": 3.0, "gamg_levels": 3}]
    w, k, n = 1e-6, 30.0, 8000
    t1, parts1 = weak.model(w, counts, n, 1, k)
    assert abs(t1 - k * w * n) < 1e-15 and parts1["halo"] == 0.0 and parts1["reductions"] == 0.0
    t, parts = weak.model(w, counts, n, 64, k)
    halo = 8000.0 * (n / 1000) ** (2.0 / 3.0)
    assert abs(parts["halo"] - k * 20.0 * (weak.ALPHA + halo / weak.BETA)) < 1e-15
    assert abs(parts["reductions"] - k * 3.0 * 2 * weak.ALPHA * 6) < 1e-15
    levels = 3 + np.log(64) / np.log(8)
    assert abs(t - (parts["local"] + parts["halo"] + parts["reductions"] + k * levels * weak.LEVEL_EXCHANGES
                    * weak.ALPHA)) < 1e-12


def test_memory_share_model_covers_the_recorded_two_rank_runs():
    """solvers.memory.per_rank is conservative against every recorded 3-D pair of runs (same suite,
    level, strategy on 1 and 2 ranks, above the redundant-factorisation size): the largest rank's
    peak less one process is at most per_rank(1-rank peak less one process, 2), and more than half
    of it (the model is not vacuous)."""
    from sdm_dolfinx.solvers import memory
    from sdm_dolfinx.solvers.factorisation import REDUNDANT_MAX_ROWS
    pairs = 0
    for name in ("ball", "ball-window"):
        recs = json.loads((SCRIPT.parent / "results" / f"{name}.json").read_text())["records"]
        one = {(r["size"], r["strategy"]): r for r in recs if r["ranks"] == 1 and r["status"] == "finished"}
        for r in recs:
            r1 = one.get((r["size"], r["strategy"]))
            if r["ranks"] != 2 or r1 is None or r["dofs"] <= REDUNDANT_MAX_ROWS:
                continue
            base = memory.BYTES_PER_PROCESS / 2 ** 20
            got, single = max(r["peak_rss_mb"]) - base, max(r1["peak_rss_mb"]) - base
            assert single / 2 < got <= memory.per_rank(single, 2), (name, r["size"], r["strategy"], got, single)
            pairs += 1
    assert pairs >= 4
