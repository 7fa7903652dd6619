"""# An elastic ball bouncing on a rigid plane, against Hertz (issue 19)

A linear elastic ball (radius 20 mm, E = 10 N/mm^2, nu = 0.3, rho = 1000 kg/m^3) falls at
v = 0.1 m/s onto the rigid plane z = 0 from 0.01 mm above it, stays in frictionless contact
about 4 ms and rebounds. Hertz's quasi-static theory (``sdm_dolfinx.problems.ball.hertz``,
derived in that module's docstring) predicts the contact time t_c = 3.90 ms, the peak force
F_max = 3.16 N, the approach delta_max = 0.133 mm and the pressure p0 sqrt(1 - r^2/a^2) on the
contact disc of radius a = 1.63 mm. The demo runs

* the singular dynamic method, P2 displacement / P1 velocity (P2/P1), at dt = 4e-5 s and
  1e-5 s, and
* the standard P2 method (P2/P2, consistent mass) at dt = 1e-5 s,

with the midpoint scheme and contact at the boundary vertices of the lower hemisphere, on
curved P2 tetrahedra refined toward the contact point (``--level``, default 1: 6.6k dofs). It
prints t_c, F_max, delta_max and the rebound speed against Hertz and writes, to
``demos/output/ball/`` (or ``--out``):

* ``ball_hertz.png``: the contact force against Hertz's F(t), and the energy of each run
  (P2/P1 conserves it through the impact, P2/P2 gains ~20 % while in contact);
* ``ball_pressure.png``: the nodal contact pressures at maximal compression against Hertz's;
* ``ball_P2-P1/``: the P2/P1 run at dt = 4e-5 s (``timeseries.csv``, ``run.json``,
  ``solution.xdmf`` every 5 steps with the P2 geometry, which ParaView opens).

With the ``CI`` variable set only the P2/P1 run at dt = 4e-5 s is made. Run with
``python demos/ball.py [--level 1] [--out DIR]``; ``mpirun -n 2`` works too (about 40 s).
"""
import argparse
import os
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.validation import hertz
from sdm_dolfinx.study.plotting import COLOURS, pyplot, save

COMM = MPI.COMM_WORLD
#: (pair, dt) of the runs (the first also writes its files)
RUNS = (("P2/P1", 4e-5), ("P2/P1", 1e-5), ("P2/P2", 1e-5))


def run_all(level, runs, out):
    """One :func:`sdm_dolfinx.validation.hertz.run_one` row per (pair, dt), with its energy history."""
    rows = []
    for k, (pair, dt) in enumerate(runs):
        folder = Path(out) / f"ball_{pair.replace('/', '-')}" if k == 0 else None
        row = hertz.run_one(level, dt, pair=pair, comm=COMM, out=folder, write_every=5)
        rows.append(row)
        if COMM.rank == 0:
            reb = "-" if row["rebound"] is None else f"{row['rebound']:.4f} v"
            print(f"{pair} dt = {dt:g} s ({row['dim_W']} dofs, {row['seconds']:.0f} s): "
                  f"t_c = {1e3 * row['t_c']:.3f} ms "
                  f"({100 * row['err_t_c']:+.1f} %), F_max = {row['F_max']:.3f} N ({100 * row['err_F_max']:+.1f} %), "
                  f"delta_max = {row['delta_max']:.4f} mm ({100 * row['err_delta_max']:+.1f} %), rebound {reb}, "
                  f"largest energy deviation {100 * row['energy_max_dev']:.2f} %", flush=True)
    return rows


def plot_force_and_energy(rows, path):
    """Left: the contact force of every run against Hertz's; right: the energy relative to E^0."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    ref = rows[0]["hertz"]
    t = np.linspace(0.0, hertz.T_FACTOR * ref["t_c"], 600)
    axes[0].plot(1e3 * t, hertz.hertz_history(ref, t)[1], "k", lw=1.8, label="Hertz", zorder=10)
    for k, r in enumerate(rows):
        h, c = r["history"], COLOURS[k % len(COLOURS)]
        lab = f"{r['pair']}, dt = {r['dt']:g} s"
        tt = 1e3 * (np.asarray(h["t"]) - r.get("t_touch", 0.0))
        # P2/P2's force chatters from step to step: drawn faint and below, it would hide the others
        style = dict(color=c, label=lab, lw=0.6 if r["pair"] == "P2/P2" else 1.3,
                     alpha=0.45 if r["pair"] == "P2/P2" else 1.0, zorder=len(rows) - k)
        axes[0].plot(tt, h["F"], **style)
        axes[1].plot(tt, np.asarray(h["energy"]) / h["energy"][0] - 1.0, **style)
    axes[0].set_ylabel("contact force (N)")
    axes[1].set_ylabel("(E - E0) / E0")
    for ax in axes:
        ax.set_xlabel("t after the touch (ms)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"ball on a rigid plane, level {rows[0]['level']} ({rows[0]['dim_W']} P2 dofs), midpoint scheme")
    fig.tight_layout()
    return save(fig, path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0].lstrip("# "))
    parser.add_argument("--level", type=int, default=1, help="mesh level (default 1: 6.6k P2 dofs)")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "output" / "ball")
    args = parser.parse_args()
    if COMM.rank == 0:
        args.out.mkdir(parents=True, exist_ok=True)
    rows = run_all(args.level, RUNS[:1] if os.environ.get("CI") else RUNS, args.out)
    if COMM.rank == 0:
        ref = rows[0]["hertz"]
        print(f"Hertz: t_c = {1e3 * ref['t_c']:.3f} ms, F_max = {ref['F_max']:.3f} N, delta_max = "
              f"{ref['delta_max']:.4f} mm, a = {ref['a']:.3f} mm, p0 = {ref['p0']:.3f} N/mm^2")
        print("wrote", args.out / plot_force_and_energy(rows, args.out / "ball_hertz.png"))
        print("wrote", args.out / hertz.plot_pressure([r for r in rows if r["pair"] == "P2/P1"],
                                                      args.out / "ball_pressure.png"))
