"""One ball bounce against Hertz at a large level, timed, with its memory: run once and recorded.

The whole bounce of :func:`sdm_dolfinx.validation.hertz.run_one` (from 0.01 mm above the plane to 1.25
Hertz contact times after the touch, ``--linear auto``: ``cg-pmg`` where a factorisation would not fit),
with the wall time, the time per step, each rank's peak RSS (VmHWM) and Hertz's contact time and peak
force against the run's. Recorded in ``results/hertz-level<L>.json`` and bench/README.md.

    mpirun -n 2 python bench/hertz_level.py --level 6            # ~1 M dofs
"""
import argparse
import json
import sys
import time
from pathlib import Path

from mpi4py import MPI

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from sdm_dolfinx.validation import hertz  # noqa: E402


class _Timed(hertz.PressureAtPeak):
    """The study's observer, also taking the wall clock at every step (the time to a given step)."""

    def __init__(self):
        super().__init__()
        self.clock = []

    def __call__(self, state):
        self.clock.append((state.n, time.perf_counter()))
        super().__call__(state)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=int, default=6)
    ap.add_argument("--dt", type=float, default=4e-5)
    ap.add_argument("--out", type=Path, default=HERE / "results", help="results folder")
    args = ap.parse_args(argv)
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    timed = []
    hertz.PressureAtPeak = lambda: timed.append(_Timed()) or timed[-1]      # run_one's observer, timed
    row = hertz.run_one(args.level, args.dt, comm=comm)
    wall = time.perf_counter() - t0
    clock = dict(timed[0].clock)
    start = clock.get(0, t0)
    hwm = [float(line.split()[1]) * 1024.0 for line in open("/proc/self/status") if line.startswith("VmHWM:")][0]
    peaks = comm.gather(hwm, root=0)
    if comm.rank == 0:
        ref = row["hertz"]
        steps = len(row["history"]["t"]) - 1
        rec = {k: row[k] for k in ("level", "dt", "pair", "dim_W", "ranks", "t_c", "F_max", "delta_max", "setup_seconds")}
        rec.update(wall_seconds=wall, steps=steps, peak_rss_gb=[p / 1e9 for p in peaks],
                   seconds_to_step={n: clock[n] - t0 for n in (25, 75, steps) if n in clock},
                   seconds_of_steps_1_to_75=clock[75] - start if 75 in clock else None,
                   t_c_hertz=ref["t_c"], F_max_hertz=ref["F_max"],
                   t_c_error=row["t_c"] / ref["t_c"] - 1.0, F_max_error=row["F_max"] / ref["F_max"] - 1.0)
        (args.out / f"hertz-level{args.level}.json").write_text(json.dumps(rec, indent=1))
        print(json.dumps(rec, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
