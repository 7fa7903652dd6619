"""# A problem of your own: an elastic bar hitting a rigid wall

This demo runs a problem that is not in the paper, without touching the package: the
problem file ``demos/bar_problem.py`` declares it (a :class:`sdm_dolfinx.problems.Problem`
is plain data: a mesh, the forms a and l, initial state, the constrained vertices and their
bounds, built in about forty lines, plus its parameters declared once), and
``sdm_dolfinx.simulate`` runs it like the membrane or the disc; so does the command line,
``python -m sdm_dolfinx run --problem-file demos/bar_problem.py``.

The problem: a straight elastic bar, length L and height H, moves with velocity v toward
a rigid wall at x = 0, which its left end face reaches after the gap d (t_0 = d / v).
Frictionless unilateral contact x + u_x >= 0 holds at the vertices of that face. With
Poisson's ratio 0 (Lamé lambda = 0, E = 2 mu) the 2-D solution is *exactly* the 1-D one,
u = (f(x, t), 0) with f_tt = c^2 f_xx, c = sqrt(E / rho): the lateral stress lambda eps_xx
vanishes, so the free top and bottom faces are traction-free without lateral motion (for
nu != 0 the bar would have to bulge, and the 1-D result would hold only for H << L and
slow loading). The 1-D solution is classical: a compression wave of stress

    sigma = rho c v   (constant)

runs from the wall to the free end, reflects as an unloading wave and returns; the bar
leaves the wall after

    t_contact = 2 L / c

at velocity +v, unstressed (energy and the momentum balance 2 m v = sigma H t_contact
hold exactly). The discrete solution differs by the space and time discretisation errors:
a wave front smeared over a few cells (numerical dispersion), which shifts the release
time by O(h / c) and puts oscillations on the stress plateau; the time average of the
stress over the contact stays close to rho c v because the discrete momentum balance is
exact. ``tests/test_api.py`` checks both numbers.

Units: mm, N, s, tonne (as the disc), a steel bar: L = 100 mm, H = 10 mm, E = 200 GPa,
rho = 7.85e-9 t/mm^3 (7850 kg/m^3), v = 1 m/s; then c = 5048 m/s, t_contact = 39.6 us and
sigma = 39.6 N/mm^2 (MPa).

Run: ``python demos/custom_problem.py [--pair P2/P1] [--Nx 40] [--out DIR]`` (also with
``mpirun -n 2``). It prints the measured and exact numbers and writes, under
``demos/output/bar/``:

* ``bar_contact.png``: the contact stress against time for the chosen pair and for the
  standard Galerkin method P2/P2 (H^h = W^h), with the closed form;
* ``bar_wave.png``: the axial stress along the bar against time (x-t diagram), with the
  characteristics x = d + c (t - t0) of the exact solution;
* the run's ``timeseries.csv``, ``run.json`` and ``solution.xdmf`` (open it in ParaView).
"""
import argparse
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import problems
from sdm_dolfinx.run import simulate

#: the problem file that declares the bar (its parameters, build function and run defaults)
PROBLEM_FILE = Path(__file__).resolve().with_name("bar_problem.py")


def bar_spec():
    """The declaration of ``bar_problem.py``, with its closed form as ``exact``: nu = 0 makes the
    plane bar's motion exactly the 1-D one of the built-in ``bar`` problem (problems/bar.py,
    whose docstring derives it), u = (u_1D(x - d, t), 0) with the gap d
    (:class:`sdm_dolfinx.problems.bar.PlaneBarExact`); a comparison of methods on this file then
    measures its errors against it."""
    return problems.load_file(PROBLEM_FILE)


def bar_problem(comm=MPI.COMM_WORLD, **values):
    """The bar of ``bar_problem.py`` for these parameter values (L, H, E, rho, v, Nx, Ny, gap_time)."""
    return bar_spec().problem(comm, **values)


def closed_form(problem):
    """The 1-D solution's numbers: first contact t0, duration 2L/c, stress rho c v (and c)."""
    ex = bar_spec().exact(problem)
    return {"c": ex.c, "t0": ex.t0, "duration": ex.t1 - ex.t0, "stress": ex.stress}


def contact_measures(result, problem):
    """Contact start, duration and stresses of a run, read from its time series.

    The multiplier of step n -> n+1 acts on that step (for the midpoint scheme, on
    U^{n+1/2}), so the contact lasts dt times the number of steps with a positive contact
    force. ``mean_stress`` is the impulse (sum of force x dt) over duration x H;
    ``plateau_stress`` the median of the face-averaged stress over the contact steps.
    """
    ts = result.timeseries
    dt = result.info["dt"]
    H = problem.parameters["H"]
    stress = ts["contact_force"][1:] / H
    on = np.flatnonzero(stress > 0)
    if on.size == 0:
        return {"t_first": np.nan, "duration": 0.0, "mean_stress": 0.0, "plateau_stress": 0.0,
                "peak_stress": 0.0, "contiguous": True}
    duration = on.size * dt
    return {"t_first": on[0] * dt, "duration": duration, "mean_stress": stress.sum() * dt / duration,
            "plateau_stress": float(np.median(stress[on])), "peak_stress": float(stress.max()),
            "contiguous": bool(on[-1] - on[0] + 1 == on.size)}


def run(pair="P2/P1", Nx=40, Ny=4, cfl=0.5, after=0.5, out=None, write_every=None, comm=MPI.COMM_WORLD, **kw):
    """Build the bar, run it through the contact and a little after; returns (problem, result).

    Args:
        pair: the (W^h, H^h) pair.
        Nx, Ny: the mesh.
        cfl: dt = cfl h / c with h = L / Nx.
        after: run until t0 + (1 + after) 2L/c.
        out: output folder (CSV, run.json, XDMF) or None.
        **kw: the bar's other parameters (L, H, E, rho, v, gap_time).
    """
    problem = bar_problem(comm, Nx=Nx, Ny=Ny, **kw)      # for its closed form
    exact = closed_form(problem)
    dt = cfl * problem.parameters["L"] / Nx / exact["c"]
    T = exact["t0"] + (1.0 + after) * exact["duration"]
    result = simulate(PROBLEM_FILE, {"Nx": Nx, "Ny": Ny, **kw}, out=out, overwrite=True, comm=comm, pair=pair,
                      scheme="midpoint", dt=dt, T=T, write_every=write_every)
    return problem, result


def plot_contact(results, problem, png):
    """Contact stress (mean over the end face) against time for each run, with the closed form."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ex = closed_form(problem)
    H = problem.parameters["H"]
    us = 1e6
    fig, ax = plt.subplots(figsize=(8, 4))
    for result, style in zip(results, ("-", "-")):
        ts = result.timeseries
        # the multiplier of step n -> n+1 is drawn at the middle of the step
        tm = (ts["t"][1:] - 0.5 * result.info["dt"]) * us
        what = "standard Galerkin" if result.discretisation.pair.standard else "singular dynamic method"
        ax.plot(tm, ts["contact_force"][1:] / H, style, lw=1.2 if len(results) == 1 or not
                result.discretisation.pair.standard else 0.8, label=f"{result.info['pair']} ({what})")
    t = np.array([0.0, ex["t0"], ex["t0"], ex["t0"] + ex["duration"], ex["t0"] + ex["duration"],
                  results[0].timeseries["t"][-1]])
    s = np.array([0.0, 0.0, ex["stress"], ex["stress"], 0.0, 0.0])
    ax.plot(t * us, s, "k--", lw=1.2, label=r"1-D closed form: $\rho c v$ during $2L/c$")
    ax.set_xlabel("t (µs)")
    ax.set_ylabel("contact stress, mean over the end face (N/mm²)")
    p = problem.parameters
    ax.set_title(f"steel bar on a rigid wall: midpoint scheme, {p['Nx']} x {p['Ny']} cells, "
                 f"dt = {results[0].info['dt'] * us:.3g} µs")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def plot_wave(out, problem, png):
    """x-t diagram of the axial stress E du_x/dx along the bar's mid-line, from the run's XDMF."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from sdm_dolfinx.post.render import read_xdmf
    p, ex = problem.parameters, closed_form(problem)
    series = read_xdmf(out)
    x, y = series.points[:, 0], series.points[:, 1]
    # the mid-line's height: the median of the distinct heights (rounded: the P2 output's points carry
    # round-off, e.g. +-1e-16 around 0 with OpenBLAS, which would make duplicates)
    ys = np.unique(np.round(y, 9))
    mid = np.flatnonzero(np.isclose(y, ys[len(ys) // 2]))
    mid = mid[np.argsort(x[mid])]
    xs = x[mid]
    xc = 0.5 * (xs[1:] + xs[:-1])
    # compression counted positive, as the contact stress
    sxx = np.array([-p["E"] * np.diff(series.field("displacement", t)[mid, 0]) / np.diff(xs) for t in series.times])
    us = 1e6
    fig, ax = plt.subplots(figsize=(7, 5))
    lim = 1.5 * ex["stress"]
    im = ax.pcolormesh(xc, np.array(series.times) * us, sxx, cmap="RdBu_r", vmin=-lim, vmax=lim, shading="nearest")
    d, L, c, t0 = p["gap"], p["L"], ex["c"], ex["t0"]
    tt = np.array([t0, t0 + L / c, t0 + 2 * L / c])
    ax.plot([d, d + L, d], tt * us, "k--", lw=1, label="characteristics x = d ± c (t − t0)")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("t (µs)")
    ax.set_title(f"compressive stress along the bar, {series.run.get('pair', '')}\n(exact: {ex['stress']:.3g} MPa "
                 f"inside the dashed triangle, 0 outside)", fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    fig.colorbar(im, ax=ax, label="−σ_xx (N/mm²)")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0].lstrip("# "))
    parser.add_argument("--pair", default="P2/P1", help="(W^h, H^h) pair (default P2/P1)")
    parser.add_argument("--Nx", type=int, default=40, help="cells along the bar (default 40)")
    parser.add_argument("--Ny", type=int, default=4, help="cells across the bar (default 4)")
    parser.add_argument("--cfl", type=float, default=0.5, help="dt = cfl h / c (default 0.5)")
    parser.add_argument("--out", type=Path, default=Path("demos/output/bar"), help="output folder")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    runs = {}
    for pair in dict.fromkeys([args.pair, "P2/P2"]):
        folder = args.out / pair.replace("/", "-").replace("+", "plus")
        runs[pair] = run(pair, args.Nx, args.Ny, args.cfl, out=folder, write_every=1)
    problem, result = runs[args.pair]
    ex = closed_form(problem)
    if comm.rank == 0:
        for pair, (pb, r) in runs.items():
            got = contact_measures(r, pb)
            print(f"bar, {pair}, {args.Nx} x {args.Ny} cells, dt = {r.info['dt']:.3g} s, {r.info['steps']} steps, "
                  f"{r.info['wall_time']:.1f} s; energy deviation {r.max_energy_deviation():.1e}")
            print(f"  contact duration {got['duration'] * 1e6:8.3f} us   2L/c    = {ex['duration'] * 1e6:8.3f} us  "
                  f"({got['duration'] / ex['duration'] - 1:+.2%})")
            print(f"  mean stress      {got['mean_stress']:8.3f} MPa  rho c v = {ex['stress']:8.3f} MPa "
                  f"({got['mean_stress'] / ex['stress'] - 1:+.2%}); plateau (median) {got['plateau_stress']:.3f} "
                  f"MPa ({got['plateau_stress'] / ex['stress'] - 1:+.2%}); peak {got['peak_stress']:.3f} MPa")
        args.out.mkdir(parents=True, exist_ok=True)
        plot_contact([r for _, r in runs.values()], problem, args.out / "bar_contact.png")
        folder = args.out / args.pair.replace("/", "-").replace("+", "plus")
        plot_wave(folder, problem, args.out / "bar_wave.png")
        print(f"wrote {args.out}/bar_contact.png, bar_wave.png and the runs' files in {args.out}/<pair>/")
