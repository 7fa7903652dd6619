"""The benchmark script runs (``--quick``: tiny sizes, seconds) and writes its results in the
documented format. No timing is asserted: timings depend on the machine and its load."""
import importlib.util
import json
from pathlib import Path

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
