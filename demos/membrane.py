# # A membrane over an obstacle: the paper's comparison of pairs
#
# This demo reproduces the membrane study of Renard (2010), §4, Figs. 2–6. It shows how to
#
# * run a registered problem with `sdm_dolfinx.simulate`, as the command line does, so that
#   every run leaves its files (`timeseries.csv`, `run.json`, `solution.xdmf`);
# * read a run back from its files and plot it;
# * tell a well-posed pair (W^h, H^h) from an ill-posed one by its energy.
#
# Run it with `python demos/membrane.py [--out DIR] [--T 0.8]` (or `make demo`;
# `mpirun -n 2` works too). With the `CI` environment variable set, the runs stop at T = 0.5.
#
# ## The problem
#
# A square membrane, fixed at height 0.02 on its boundary and pulled down by the load
# f = −0.6, starts at rest at u = 0.02, falls onto the obstacle u ≥ 0, bounces and falls
# again. Its discrete energy J^h (the paper's Theorem 2) is conserved by the midpoint scheme
# between impacts; at an impact it is conserved in the limit dt → 0 only if the pair
# satisfies the inf-sup condition (7). The pairs of the paper:
#
# | pair   | displacement W^h / velocity H^h | the paper            |
# |--------|---------------------------------|----------------------|
# | P1+/P0 | P1 + cubic bubble / P0          | well-posed (Lemma 2) |
# | P1/P0  | P1 / P0                         | ill-posed            |
# | P1/P1  | P1 / P1 (standard Galerkin)     | ill-posed            |
# | P1+/P1 | P1 + cubic bubble / P1          | stable, no proof     |
# | P2/P1  | P2 / P1                         | stable, no proof     |

import argparse
import csv
import os
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.run import simulate

PAIRS = ["P1+/P0", "P1/P0", "P1/P1", "P1+/P1", "P2/P1"]
WELL_POSED = ["P1+/P0", "P1+/P1", "P2/P1"]
TIME_STEPS = [1e-2, 1e-3]


# ## Running every pair
#
# `simulate` runs a declared problem by name with its parameters (`{"N": N}`: the mesh has N × N
# squares, h = 1/N; the paper's is N = 10) and the run options of the command line
# (`python -m sdm_dolfinx membrane --N 10 --pair P2/P1 --dt 1e-3 --out DIR` is the same run).
# Each (pair, dt) gets its own folder; `write_every=50` stores the fields every 50 steps.


def run_dir(out, pair, dt):
    return Path(out) / f"{pair.replace('/', '-').replace('+', 'plus')}_dt{dt:g}"


def run_all(out, T, N=10):
    """Run every (pair, dt) into its own folder: {(pair, dt): (folder, time series)}."""
    runs = {}
    for pair in PAIRS:
        for dt in TIME_STEPS:
            d = run_dir(out, pair, dt)
            result = simulate("membrane", {"N": N}, out=d, overwrite=True, pair=pair, dt=dt, T=T, write_every=50)
            runs[pair, dt] = (d, result.timeseries)
    return runs


# ## Reading a run back
#
# A run's `timeseries.csv` has one row per step (row 0 is t = 0): `t`, `energy`, `u_probe`
# (the displacement at the centre), `lambda_probe` (the contact stress there), `n_active`
# (vertices in contact), ... (`docs/outputs.md`). The standard library
# reads it; so would numpy or pandas.


def read_series(folder):
    with open(Path(folder) / "timeseries.csv") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def energy_deviation(series):
    """max_n |J^n − J^0| / J^0."""
    E = series["energy"]
    return float(np.max(np.abs(E - E[0])) / E[0])


# ## Figures
#
# One figure per pair, as in the paper: the energy, the displacement and the contact stress
# at the centre against time, for both time steps.


def plot_pair(pair, folders, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for dt in TIME_STEPS:
        s = read_series(folders[pair, dt])
        lw = 1.6 if dt == TIME_STEPS[0] else 1.0
        axes[0].plot(s["t"], s["energy"], lw=lw, label=f"dt = {dt:g}")
        axes[1].plot(s["t"], s["u_probe"], lw=lw, label=f"dt = {dt:g}")
        axes[2].plot(s["t"], s["lambda_probe"], lw=lw, label=f"dt = {dt:g}")
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


# A 3-D picture of one run, drawn from its `solution.xdmf` by `sdm_dolfinx.post.render`
# (pyvista off-screen when installed, else matplotlib): the membrane warped over the obstacle
# plane, the vertices in contact in red.


def picture_3d(folder, out, time=0.3):
    """The membrane on the obstacle at ``time`` (rank 0 only)."""
    from sdm_dolfinx.post import render
    png = Path(out) / "membrane_3d.png"
    how = render.picture(folder, png, time=time)
    return png, how


# ## Running the demo

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="A membrane over an obstacle: the paper's comparison of pairs")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "output" / "membrane",
                        help="output folder")
    parser.add_argument("--T", type=float, default=0.5 if os.environ.get("CI") else 0.8,
                        help="final time (default 0.8; 0.5 when CI is set; at least 0.3)")
    args = parser.parse_args()
    if args.T < 0.3:
        parser.error("--T must be at least 0.3: the first impact is at t ~ 0.25")
    comm = MPI.COMM_WORLD
    runs = run_all(args.out, args.T)
    folders = {key: folder for key, (folder, _) in runs.items()}
    deviation = {key: energy_deviation(series) for key, (_, series) in runs.items()}
    if comm.rank == 0:
        for pair in PAIRS:
            png = plot_pair(pair, folders, args.out)
            print(f"{pair:7s} max |J - J0|/J0: dt=1e-2 {deviation[pair, 1e-2]:9.3%}, dt=1e-3 "
                  f"{deviation[pair, 1e-3]:9.3%}  -> {png}")
        png, how = picture_3d(folders["P1+/P0", 1e-3], args.out, time=min(0.3, args.T))
        print(f"wrote {png} ({how})")

    # ## What the runs show
    #
    # Every run reaches the obstacle (the first impact is at t ≈ 0.25).
    for (pair, dt), (_, series) in runs.items():
        assert series["n_active"].max() > 0, f"{pair}, dt = {dt}: no vertex reached the obstacle"
    # A well-posed pair conserves the energy through the impacts as dt → 0: at dt = 1e-3 its
    # largest deviation is a few per cent at most (measured 0.08–1.7 % at T = 0.8) and at least
    # five times smaller than at dt = 1e-2 (measured 10–40 times).
    for pair in WELL_POSED:
        fine, coarse = deviation[pair, 1e-3], deviation[pair, 1e-2]
        assert fine < 0.05 and fine < coarse / 5, f"{pair}: energy deviation {coarse:.2%} -> {fine:.2%}"
    # An ill-posed pair does not: its energy more than doubles at the impacts, and more so at
    # the smaller time step (measured: P1/P0 568 %, P1/P1 225 % at dt = 1e-3).
    for pair in ("P1/P0", "P1/P1"):
        fine, coarse = deviation[pair, 1e-3], deviation[pair, 1e-2]
        assert fine > 1.0 and fine > coarse, f"{pair}: energy deviation {coarse:.2%} -> {fine:.2%}"
    if comm.rank == 0:
        print("checked: every pair reaches the obstacle; the well-posed pairs keep their energy as dt falls, "
              "the ill-posed ones more than double it")
