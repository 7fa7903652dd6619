"""The cost of finite strain: a hyperelastic contact step against the linear one, full and modified Newton.

For each problem and level, the same window of steps through the first impact is run with the linear
material and with ``neo-hookean`` (``--newton full``, ``modified`` and ``initial``), one rank, ``--linear auto``
(the linear runs factorise K once; a hyperelastic run factorises every tangent, through the augmented
[c_A T, sqrt(c_M) B^T; sqrt(c_M) B, -D] where that is sparser). Recorded per run: the wall time of the
steps (set-up apart), the time per step, per contact step (a step with an active constraint), the Newton
iterations and tangents per step, and the ratio to the linear run's time per contact step.

    python bench/finite_strain.py --problem disc --levels 1 2 3 4 5
    python bench/finite_strain.py --problem ball --levels 1 2

Windows: the disc (v0 = -1000 mm/s from 0.2 mm, gravity) 40 steps of dt = 5e-4 / 2^(level - 1) (its h halves
per level; at dt 5e-4 the level-3 impact did not converge), contact from step 1; the ball (v = 100 mm/s,
0.01 mm above the plane) 50 steps of 4e-5 s, contact from step 1. Results in
``results/finite_strain_<problem>.json`` and bench/README.md.
"""
import argparse
import json
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from sdm_dolfinx import simulate  # noqa: E402

#: per problem: its parameters, dt at level 1 (halved per level on the disc, whose h halves) and the steps
WINDOWS = {"disc": dict(params={"height": 0.2}, dt=5e-4, halve=True, steps=40),
           "ball": dict(params={}, dt=4e-5, halve=False, steps=50)}
RUNS = (("linear", "full"), ("neo-hookean", "full"), ("neo-hookean", "modified"), ("neo-hookean", "initial"))


def one(problem, level, material, newton):
    """The measured row of one run."""
    w = WINDOWS[problem]
    dt = w["dt"] / 2 ** (level - 1) if w["halve"] else w["dt"]
    clock = []
    t0 = time.perf_counter()
    r = simulate(problem, {"level": level, **w["params"]}, material=material, newton=newton, dt=dt,
                 T=w["steps"] * dt, on_step=lambda n, row: clock.append(time.perf_counter()))
    ts = r.timeseries
    steps = np.diff([r.info["setup_time"] + t0] + clock) if clock else np.zeros(0)
    contact = ts["n_active"][1:] > 0
    row = {"problem": problem, "level": level, "material": material, "newton": newton, "dofs": r.info["dim_W"], "dt": dt,
           "steps": int(len(steps)), "contact_steps": int(contact.sum()), "wall_steps_s": float(steps.sum()),
           "s_per_step": float(steps.mean()),
           # the median: the first step also opens the run's files (at level 1 it doubled the linear mean)
           "s_per_contact_step": float(np.median(steps[contact])) if contact.any() else None,
           "setup_s": float(r.info["setup_time"])}
    if "nonlinear_its" in ts:
        row.update(newton_its_per_step=float(ts["nonlinear_its"][1:].mean()),
                   newton_its_max=int(ts["nonlinear_its"].max()), tangents_per_step=float(ts["tangents"][1:].mean()))
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", choices=sorted(WINDOWS), default="disc")
    ap.add_argument("--levels", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--out", type=Path, default=HERE / "results")
    a = ap.parse_args(argv)
    rows = []
    for level in a.levels:
        base = None
        for material, newton in RUNS:
            try:
                row = one(a.problem, level, material, newton)
            except Exception as e:                 # a failed run is recorded, not the end of the study
                row = {"problem": a.problem, "level": level, "material": material, "newton": newton,
                       "failed": str(e).splitlines()[0][:200]}
            if material == "linear":
                base = row.get("s_per_contact_step")
            elif base and "failed" not in row:
                row["vs_linear_contact_step"] = row["s_per_contact_step"] / base
            rows.append(row)
            if MPI.COMM_WORLD.rank == 0:
                print(json.dumps(row), flush=True)
    if MPI.COMM_WORLD.rank == 0:
        a.out.mkdir(parents=True, exist_ok=True)
        (a.out / f"finite_strain_{a.problem}.json").write_text(json.dumps(
            {"date": time.strftime("%Y-%m-%d"), "ranks": MPI.COMM_WORLD.size, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
