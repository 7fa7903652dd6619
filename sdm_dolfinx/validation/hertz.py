"""The ball against Hertz: t_c, F_max, delta_max and the pressure profile, at levels and dt.

Each run is the ball problem (:mod:`sdm_dolfinx.problems.ball`, its defaults: R = 20 mm, E = 10
N/mm^2, nu = 0.3, rho = 1e-9 t/mm^3, v = 100 mm/s) at a mesh level and a time step, run from
0.01 mm above the plane until 1.25 Hertz contact times after the touch. From its time series:

- t_c: the number of steps of the first contact phase (contact force > 0) times dt (the
  force of step n+1 is the step's impulse / dt, so t_c is resolved to dt);
- F_max: the largest contact force (N);
- delta_max: the largest approach of the centre of mass below its position at the touch,
  from e^T M U = the trapezoidal sum of the momentum (exact for the midpoint scheme:
  U^{n+1} - U^n = dt (V^{n+1} + V^n)/2), divided by the mesh's mass;
- the rebound coefficient v_out / v (v_out: the momentum after the contact / mass);

against Hertz's quasi-static closed forms (:func:`sdm_dolfinx.problems.ball.hertz`). At the step
of largest contact force, the nodal pressures lambda_i / |Gamma_i| of the contact vertices are
plotted against their distance r from the axis, with Hertz's p0 sqrt(1 - r^2/a^2).

    python -m sdm_dolfinx.validation.hertz --runs 1:4e-5 1:2e-5 2:4e-5 2:2e-5 --out report/hertz
    mpirun -n 2 python -m sdm_dolfinx.validation.hertz --runs 3:4e-5 --out report/hertz3

writes ``hertz.json`` (the rows, with the force histories), ``hertz.md`` (the table),
``hertz_force.png`` (F(t) of every run against Hertz's) and ``hertz_pressure.png``
(``--replot A.json B.json`` redraws them from finished studies). ``make figures`` runs the same study
(resumably, levels 1-3) for the report's section "3-D: the ball against Hertz"
(:mod:`sdm_dolfinx.report.hertz_entry`).

Measured (P2/P1, midpoint, 1 rank; Hertz: t_c = 3.900 ms, F_max = 3.161 N, delta_max = 0.1325 mm;
t_c is resolved to dt, i.e. +-1 % at dt = 4e-5 s)::

    level  dim W   a/h_c  dt (s)  err t_c  err F_max  err delta_max  max |E-E0|/E0  wall
    1        6594    2    4e-5    +7.7 %    -2.9 %      +10.4 %        0.18 %        7 s
    1        6594    2    2e-5    +8.2 %    -2.7 %      +10.4 %        0.28 %        9 s
    2       21750    4    4e-5    +1.5 %    +0.15 %     +3.4 %         0.16 %       23 s
    2       21750    4    2e-5    +2.6 %    +0.13 %     +3.4 %         0.05 %       36 s
    3       53976    6    2e-5    +1.0 %    +1.45 %     +1.6 %         0.04 %      156 s *
    4      107397    8    4e-5    -0.5 %    +1.9 %      +0.7 %         0.13 %      344 s *, 6.1 GB

(* measured with the dense Schur path allowed up to 1000 active constraints, the step
solver's threshold in 3-D since (``solvers.schur.SCHUR_MAX_ACTIVE_3D``). With the 2-D threshold 100 the level-3 contact steps fell back to CG preconditioned
by the factorisation, 24 solves per Newton iteration: 754 s for 125 steps of 4e-5 s instead
of 83 s.) The rebound speed is 0.9999 v at every level.

The remaining dynamic correction: Hertz's theory is quasi-static, and the default ball's contact
lasts only 4.8 periods of its slowest vibration (0.81 ms). With v = 1 mm/s instead (t_c = 9.8 ms,
12 periods, v/c = 1e-5, dt = 1e-4 s, the mesh refined for its own a) the same levels give t_c
+4.1 / +3.1 %, F_max -2.3 / -1.4 %, delta_max +5.4 / +3.6 % (levels 2 / 3): the discrete contact
converges to Hertz from the soft side (the vertex-only constraint lets the P2 mid-edge nodes of
the contact zone sink below the plane, 0.06 mm at level 1 against delta_max = 0.13 mm; and a
ball is a little more compliant than Hertz's half-space), while at v = 100 mm/s the impact's
dynamics add about +3 % to F_max and -2 % to t_c and delta_max (level 3: the two speeds'
difference). The finest level's errors (t_c -0.5 %, F_max +1.9 %) are of that size.
"""
import argparse
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.mpiutil import atomic_write_text, gather_rows, json_text
from sdm_dolfinx.study.plotting import COLOURS, pyplot, save
from sdm_dolfinx.problems import ball
from sdm_dolfinx.run import num_steps, simulate

#: (level, dt) of the default study: about 2 minutes on one core
DEFAULT_RUNS = ((1, 4e-5), (1, 2e-5), (2, 4e-5), (2, 2e-5))
#: the runs end this many Hertz contact times after the touch (the release and a little flight)
T_FACTOR = 1.25


def hertz_history(ref, t):
    """Hertz's approach delta(t) (mm) and force F(t) (N) at the times ``t`` after the touch.

    With s = delta / delta_max the energy gives t(s) = (delta_max / v) int_0^s dx / sqrt(1 -
    x^(5/2)) = (delta_max / v) (2/5) B(2/5, 1/2) I(s^(5/2); 2/5, 1/2) (I the regularised incomplete
    Beta function) up to delta_max at t_c / 2, and the release is its mirror image; inverted here
    by interpolation on a fine grid of s.
    """
    from scipy.special import betainc
    s = np.linspace(0.0, 1.0, 20001)
    half = 0.5 * ref["t_c"]
    ts = half * betainc(0.4, 0.5, s ** 2.5)           # t(s), increasing from 0 to t_c / 2
    t = np.asarray(t, dtype=float)
    tt = np.where((t >= 0) & (t <= ref["t_c"]), np.minimum(t, ref["t_c"] - t), -1.0)
    delta = np.where(tt >= 0, np.interp(tt, ts, s), 0.0) * ref["delta_max"]
    return delta, ref["F_max"] * (delta / ref["delta_max"]) ** 1.5


def contact_phase(force):
    """(first, end): the first contact phase is steps first .. end - 1 (force > 0); (None, None) without."""
    on = np.flatnonzero(np.asarray(force) > 0)
    if not on.size:
        return None, None
    first = int(on[0])
    off = np.flatnonzero(np.asarray(force)[first:] <= 0)
    return first, first + int(off[0]) if off.size else len(force)


def metrics(ts, dt, mass, height, v, ref):
    """The run's t_c, F_max, delta_max, rebound and energy numbers, and their errors against ``ref``.

    Args:
        ts: the time series (``t``, ``contact_force``, ``momentum_y`` = the z-momentum, ``energy``).
        dt: the time step (s). mass: e^T M e (t). height: the initial gap (mm). v: the speed (mm/s).
        ref: :func:`sdm_dolfinx.problems.ball.hertz`.
    """
    F, p, E = (np.asarray(ts[k], dtype=float) for k in ("contact_force", "momentum_y", "energy"))
    first, end = contact_phase(F)
    out = {"released": bool(first is not None and end < len(F)),
           "energy_max_dev": float(np.max(np.abs(E - E[0])) / E[0]),
           "energy_final_dev": float(abs(E[-1] - E[0]) / E[0])}
    if first is None:
        return {**out, "t_c": 0.0, "F_max": 0.0, "delta_max": 0.0, "rebound": None}
    # the centre's displacement along z: e^T M U / m, U^{n+1} - U^n = dt (V^{n+1} + V^n) / 2
    w = np.concatenate([[0.0], np.cumsum(0.5 * dt * (p[1:] + p[:-1]))]) / mass
    out.update(t_c=(end - first) * dt, F_max=float(F[first:end].max()), delta_max=float(np.max(-w - height)),
               rebound=float(p[-1] / mass / v) if out["released"] else None, t_touch=float(ts["t"][first] - dt))
    for k in ("t_c", "F_max", "delta_max"):
        out[f"err_{k}"] = out[k] / ref[k] - 1.0
    return out


class PressureAtPeak:
    """``simulate``'s observer: the multipliers lambda_i, lumped areas |Gamma_i| and radii r_i of the
    constrained vertices at the step of largest contact force (gathered by :meth:`result`)."""

    #: it changes nothing of the run (the run need not watch its forms: sdm_dolfinx.method.frozen)
    read_only = True

    def __init__(self):
        self.best, self.t = -1.0, None
        self.r = self.lam = self.area = np.zeros(0)

    def __call__(self, state):
        if state.n == 0:
            return
        lam = np.asarray(state.lam)
        d = state.discretisation
        F = d.comm.allreduce(float(np.sum(lam)), op=MPI.SUM)
        if F > self.best:
            self.best, self.t = F, state.t
            self.r, self.lam, self.area = np.hypot(d.cx[0], d.cx[1]), lam.copy(), np.asarray(d.cmeasure).copy()

    def result(self, comm):
        """{r, lam, area, t, F} of every constrained vertex at the peak on rank 0 (None elsewhere)."""
        parts = [gather_rows(a, comm) for a in (self.r, self.lam, self.area)]
        if comm.rank != 0:
            return None
        return {"r": parts[0].tolist(), "lam": parts[1].tolist(), "area": parts[2].tolist(), "t": self.t,
                "F": self.best}


def ring_pressure(peak, width):
    """The pressure averaged over rings of ``width``: sum lambda_i / sum |Gamma_i| of the vertices with
    r_i in each ring (the force per area, which the nodal ratios scatter around); (r_mid, p)."""
    r, lam, area = (np.asarray(peak[k]) for k in ("r", "lam", "area"))
    edges = np.arange(0.0, r.max() + width, width)
    k = np.digitize(r, edges) - 1
    force, meas = np.bincount(k, lam, len(edges)), np.bincount(k, area, len(edges))
    keep = meas > 0
    return (edges + 0.5 * width)[keep], force[keep] / meas[keep]


def run_one(level, dt, pair="P2/P1", linear="auto", comm=MPI.COMM_WORLD, out=None, write_every=None,
            material=None, newton=None, **problem_args):
    """One ball run at ``level`` and ``dt``: its :func:`metrics`, force and energy histories and peak
    pressures (``out``, ``write_every``, ``material``, ``newton``: the run's folder, XDMF interval,
    material and tangent, as for ``simulate``)."""
    t0 = time.perf_counter()
    problem = ball.problem(comm, level=level, **problem_args)
    ref = ball.hertz_of(problem)
    prm = problem.parameters
    T = num_steps(prm["height"] / prm["v"] + T_FACTOR * ref["t_c"], dt) * dt     # whole steps
    peak = PressureAtPeak()
    r = simulate(problem, pair=pair, dt=dt, T=T, linear=linear, observe=peak, out=out, write_every=write_every,
                 material=material, newton=newton)
    ts = r.timeseries
    mass = ball.total_mass(problem)
    row = {"level": level, "dt": dt, "pair": pair, "h": prm["h"], "h_contact": prm["h_contact"],
           "a_over_h": ref["a"] / prm["h_contact"], "dim_W": int(r.discretisation.W.dofmap.index_map.size_global
                                                            * r.discretisation.W.dofmap.index_map_bs),
           "mass_error": mass / ref["mass"] - 1.0, "ranks": comm.size, "hertz": ref, "R2": prm.get("R2"),
           **metrics(ts, dt, mass, prm["height"], prm["v"], ref),
           "history": {k: np.asarray(ts[c]).tolist() for k, c in (("t", "t"), ("F", "contact_force"),
                                                                   ("energy", "energy"))},
           "peak": peak.result(comm), "seconds": time.perf_counter() - t0,
           "setup_seconds": r.info.get("setup_time")}
    return row


def table(rows):
    """The study's Markdown table."""
    head = ("| level | dim W | a/h_c | dt (s) | t_c (ms) | err t_c | F_max (N) | err F_max | delta_max (mm) | "
            "err delta | v_out/v | max energy dev | wall (s) |\n|" + "---|" * 13 + "\n")
    ref = rows[0]["hertz"]
    lines = [f"| Hertz | | | | {1e3 * ref['t_c']:.4f} | | {ref['F_max']:.4f} | | {ref['delta_max']:.5f} | | 1 | | |"]
    for r in rows:
        lines.append(f"| {r['level']} | {r['dim_W']} | {r['a_over_h']:.1f} | {r['dt']:.1e} | {1e3 * r['t_c']:.4f} | "
                     f"{100 * r['err_t_c']:+.2f} % | {r['F_max']:.4f} | {100 * r['err_F_max']:+.2f} % | "
                     f"{r['delta_max']:.5f} | {100 * r['err_delta_max']:+.2f} % | "
                     f"{'-' if r['rebound'] is None else format(r['rebound'], '.4f')} | "
                     f"{100 * r['energy_max_dev']:.3f} % | {r['seconds']:.0f} |")
    return head + "\n".join(lines) + "\n"


def plot_force(rows, path):
    """F(t) of every run (t from the touch) against Hertz's."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ref = rows[0]["hertz"]
    t = np.linspace(0.0, T_FACTOR * ref["t_c"], 800)
    ax.plot(1e3 * t, hertz_history(ref, t)[1], "k", lw=2.2, label="Hertz (quasi-static)")
    for k, r in enumerate(rows):
        h = r["history"]
        ax.step(1e3 * (np.asarray(h["t"]) - r.get("t_touch", 0.0)), h["F"], where="pre", color=COLOURS[k % 6],
                lw=1.0, label=f"level {r['level']}, dt = {r['dt']:.0e} s ({r['dim_W']} dofs)")
    ax.set_xlabel("t after the touch (ms)")
    ax.set_ylabel("contact force (N)")
    ax.set_xlim(0.0, 1e3 * T_FACTOR * ref["t_c"])
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    R2 = rows[0].get("R2")
    ax.set_title("ball on a rigid " + ("plane" if R2 is None else f"sphere (R2 = {R2:g} mm)")
                 + ": contact force against Hertz")
    fig.tight_layout()
    return save(fig, path)


def plot_pressure(rows, path):
    """The nodal pressures at the peak force of each level's finest-dt run against p0 sqrt(1 - r^2/a^2)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(10.5, 4.4))
    ref = rows[0]["hertz"]
    r = np.linspace(0.0, 1.6 * ref["a"], 400)
    ax.plot(r, ball.hertz_pressure(r, ref["a"], ref["p0"]), "k", lw=2.2, label="Hertz p0 sqrt(1 - r²/a²)")
    finest = {}
    for row in rows:                            # per level, the run of smallest dt
        if row["peak"] and (row["level"] not in finest or row["dt"] < finest[row["level"]]["dt"]):
            finest[row["level"]] = row
    for k, row in enumerate(finest.values()):
        pk, c = row["peak"], COLOURS[k % 6]
        rr, pp = np.asarray(pk["r"]), np.asarray(pk["lam"]) / np.asarray(pk["area"])
        keep = rr <= 1.6 * ref["a"]
        ax.plot(rr[keep], pp[keep], "o", ms=3.0, color=c, alpha=0.45,
                label=f"level {row['level']} (a/h_c = {row['a_over_h']:.0f}), dt = {row['dt']:.0e} s, "
                      f"F = {pk['F']:.3f} N: nodal")
        rm, pm = ring_pressure(pk, row["h_contact"])
        keep = rm <= 1.6 * ref["a"]
        ax.plot(rm[keep], pm[keep], "-", color=c, lw=1.6, label="... averaged over rings of width h_c")
    ax.axvline(ref["a"], color="0.5", lw=0.8, ls="--")
    ax.set_xlabel("distance r from the axis (mm)")
    ax.set_ylabel("contact pressure λ_i / |Γ_i| (N/mm²)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title("pressure at maximal compression (nodal multiplier / lumped area)")
    fig.tight_layout()
    return save(fig, path)


def study(runs=DEFAULT_RUNS, out="report/hertz", pair="P2/P1", linear="auto", comm=MPI.COMM_WORLD, say=print,
          R2=None):
    """Run ``runs`` ((level, dt) pairs); write hertz.json, hertz.md and the two PNGs to ``out`` (rank 0).
    ``R2``: the ball falls on a rigid sphere of that radius instead of the plane (Hertz with R*).

    Returns the rows (every rank)."""
    rows = []
    for level, dt in runs:
        row = run_one(level, dt, pair=pair, linear=linear, comm=comm, **({} if R2 is None else {"R2": R2}))
        rows.append(row)
        if comm.rank == 0 and say:
            say(f"level {level} dt {dt:g}: t_c {100 * row['err_t_c']:+.2f} %, F_max {100 * row['err_F_max']:+.2f} %, "
                f"delta_max {100 * row['err_delta_max']:+.2f} %, {row['seconds']:.0f} s")
    if comm.rank == 0:
        write_outputs(rows, out)
    return rows


def write_outputs(rows, out):
    """hertz.json, hertz.md and the two PNGs of ``rows`` in ``out`` (call on one rank)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "hertz.json", json_text(rows))
    atomic_write_text(out / "hertz.md", table(rows))
    plot_force(rows, out / "hertz_force.png")
    plot_pressure(rows, out / "hertz_pressure.png")


def parse_run(text):
    """``LEVEL:DT`` -> (int, float)."""
    level, dt = text.split(":")
    return int(level), float(dt)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sdm_dolfinx.validation.hertz", description=__doc__.splitlines()[0])
    ap.add_argument("--runs", nargs="+", type=parse_run, default=list(DEFAULT_RUNS), metavar="LEVEL:DT")
    ap.add_argument("--pair", default="P2/P1")
    ap.add_argument("--linear", default="auto", help="the step solver's linear strategy (see run --help)")
    ap.add_argument("--out", default="report/hertz")
    ap.add_argument("--R2", type=float, default=None, metavar="MM",
                    help="drop the ball on a rigid sphere of this radius (mm) instead of the plane (Hertz with "
                         "1/R* = 1/R + 1/R2)")
    ap.add_argument("--replot", nargs="+", default=None, metavar="JSON",
                    help="redraw from these hertz.json files (their rows joined) instead of running")
    args = ap.parse_args(argv)
    if args.replot:
        import json
        rows = [r for f in args.replot for r in json.loads(Path(f).read_text())]
        if MPI.COMM_WORLD.rank == 0:
            write_outputs(rows, args.out)
    else:
        rows = study(args.runs, args.out, args.pair, args.linear, R2=args.R2)
    if MPI.COMM_WORLD.rank == 0:
        print(table(rows), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
