"""Membrane over an obstacle: the paper's comparison of pairs (Renard 2010, Figs. 2-6).

A membrane, pre-stretched at height 0.02 and pulled down by f = -0.6, falls onto the
obstacle u >= 0, bounces and falls again. For each pair P1+/P0, P1/P0, P1/P1, P1+/P1 and
P2/P1 this demo runs the midpoint scheme on the paper's mesh (h = 0.1) with dt = 1e-2 and
1e-3, through ``sdm_dolfinx.simulate`` with an output folder (so every run leaves its
``timeseries.csv``, ``run.json`` and ``solution.xdmf``, as the command line does), and plots
from those files the energy, the displacement at the
centre and the contact stress at the centre, one PNG per pair. Well-posed pairs (P1+/P0,
P1+/P1, P2/P1) conserve energy as dt decreases; the others blow up after the first impact.
It also renders ``membrane_3d.png``: the P1+/P0 membrane (dt = 1e-3) lying on the obstacle
at t = 0.3, warped by its displacement over the obstacle plane (pyvista off-screen when
installed, else matplotlib; see ``sdm_dolfinx/post/render.py``).

Run: ``python demos/membrane.py [--out DIR] [--T 0.8]`` (or ``mpirun -n 2 python ...``).
With the ``CI`` environment variable set, the runs stop at T = 0.5.
"""
import argparse
import csv
import os
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.run import simulate

PAIRS = ["P1+/P0", "P1/P0", "P1/P1", "P1+/P1", "P2/P1"]
TIME_STEPS = [1e-2, 1e-3]


def run_dir(out, pair, dt):
    return Path(out) / f"{pair.replace('/', '-').replace('+', 'plus')}_dt{dt:g}"


def run_all(out, T, N=10):
    """Run every (pair, dt) into its own folder; returns {(pair, dt): folder}."""
    folders = {}
    for pair in PAIRS:
        for dt in TIME_STEPS:
            d = run_dir(out, pair, dt)
            simulate("membrane", {"N": N}, out=d, overwrite=True, pair=pair, dt=dt, T=T, write_every=50)
            folders[(pair, dt)] = d
    return folders


def read_series(folder):
    with open(Path(folder) / "timeseries.csv") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def plot_pair(pair, folders, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for dt, style in zip(TIME_STEPS, ("-", "-")):
        s = read_series(folders[(pair, dt)])
        lw = 1.6 if dt == TIME_STEPS[0] else 1.0
        axes[0].plot(s["t"], s["energy"], style, lw=lw, label=f"dt = {dt:g}")
        axes[1].plot(s["t"], s["u_probe"], style, lw=lw, label=f"dt = {dt:g}")
        axes[2].plot(s["t"], s["lambda_probe"], style, lw=lw, label=f"dt = {dt:g}")
    axes[0].set_title("energy $J^h$")
    axes[1].set_title("displacement at (0.5, 0.5)")
    axes[1].axhline(0.0, color="k", lw=0.6)
    axes[2].set_title("contact stress at (0.5, 0.5)")
    for ax in axes:
        ax.set_xlabel("t")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle(f"{pair}, midpoint scheme, h = 0.1")
    fig.tight_layout()
    png = Path(out) / f"membrane_{pair.replace('/', '-').replace('+', 'plus')}.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def picture_3d(folder, out, time=0.3):
    """The membrane on the obstacle at ``time``, warped over the obstacle plane (rank 0 only)."""
    from sdm_dolfinx.post import render
    png = Path(out) / "membrane_3d.png"
    how = render.picture(folder, png, time=time)
    return png, how


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="demos/output/membrane", help="output folder")
    parser.add_argument("--T", type=float, default=0.5 if os.environ.get("CI") else 0.8, help="final time")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    folders = run_all(args.out, args.T)
    if comm.rank == 0:
        for pair in PAIRS:
            s = read_series(folders[(pair, 1e-3)])
            E = s["energy"]
            png = plot_pair(pair, folders, args.out)
            print(f"{pair:7s} dt=1e-3: max |J - J0|/J0 = {np.max(np.abs(E - E[0])) / E[0]:9.3%}  -> {png}")
        png, how = picture_3d(folders[("P1+/P0", 1e-3)], args.out, time=min(0.3, args.T))
        print(f"wrote {png} ({how})")
