"""Two elastic balls colliding against Hertz's theory of two spheres: the built-in ``two_balls`` head on and
unequal, at mesh levels and time steps (``demos/two_balls.py`` and the report's section "3-D: two balls
against Hertz", :mod:`sdm_dolfinx.report.two_balls_entry`).

The cases (:data:`CASES`): two equal balls (R = 20 mm, E = 10 N/mm^2, nu = 0.3, rho = 1000 kg/m^3) at
+-100 mm/s, Hertz's F_max = 3.161 N and t_c = 3.896 ms, as the single ball on a rigid plane at 100 mm/s;
and ball 2 with R2 = 10 mm, E2 = 40 N/mm^2, rho2 = 3000 kg/m^3 at rest, struck at 100 mm/s: Hertz with
1/R* = 1/R1 + 1/R2, 1/E* = sum (1 - nu^2)/E and the reduced mass m* (``two_balls.hertz_two``),
F_max = 1.064 N, t_c = 3.16 ms. Each run starts with the balls 2 x 0.01 mm apart and ends 1.5 t_c after
they touch. From its time series (:func:`metrics`):

- t_c: the steps of the first contact phase (contact force > 0) times dt (resolved to dt);
- F_max: the largest contact force; the impulse, sum F dt, against 2 m* (v1 + v2) (an elastic rebound of
  the relative motion);
- the total momentum's largest change over ball 1's initial momentum (the contact forces are equal and
  opposite: round-off), and the energy's largest relative deviation.

Measured (P2/P1, midpoint, 1 rank; dt 4e-5 s head on, 3e-5 s unequal): level 1 F_max -2.7 % and -3.2 %, t_c
+7.7 % and +8.3 % (the single ball: +7.7 %: the contact radius spans two cells), impulse +0.08 % and +0.07 %;
level 2 (43 500 and 45 972 dofs) F_max +0.31 % and -0.73 %, t_c +1.5 % and +3.5 %, impulse +0.11 % and
+0.12 %; the total momentum constant to 6e-12 of ball 1's, the energy within 0.26 % (docs/results.md).
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.problems import two_balls
from sdm_dolfinx.validation.hertz import contact_phase, hertz_history

#: the cases: (the problem's values, the time step at level 1 (s))
CASES = {"head on": ({}, 4e-5), "unequal": ({"R2": 10.0, "E2": 40.0, "rho2": 3e-9, "v2": 0.0}, 3e-5)}
#: the run ends this many Hertz contact times after the touch
AFTER = 1.5


def run_one(case, level, dt=None, comm=MPI.COMM_WORLD, **options):
    """Run ``case`` (a key of :data:`CASES`) at ``level`` (dt: the case's own by default); returns its row
    (:func:`metrics`, the same on every rank; collective). ``options``: more run options (``out``, ...)."""
    from sdm_dolfinx.run import simulate
    values, dt0 = CASES[case]
    dt = dt0 if dt is None else dt
    p = two_balls.problem(comm, level=level, **values)
    par = p.parameters
    touch = 2.0 * par["height"] / (par["v"] + par["v2"])
    T = dt * np.ceil((touch + AFTER * par["hertz"]["t_c"]) / dt)
    result = simulate(p, pair="P2/P1", dt=dt, T=T, **options)
    return {"case": case, "level": level, "dt": dt, "dofs": int(result.info.get("dim_W", 0)),
            **metrics(result.timeseries, dt, par, touch)}


def metrics(ts, dt, par, touch):
    """The row's numbers from a run's time series (see the module); ``par`` the problem's parameters."""
    ref = par["hertz"]
    force = np.asarray(ts["contact_force"])
    first, end = contact_phase(force)
    t_c = (end - first) * dt if first is not None else 0.0
    rebound = 2.0 * ref["mass"] * (par["v"] + par["v2"])
    P, e = np.asarray(ts["momentum_y"]), np.asarray(ts["energy"])
    p1 = np.asarray(ts["momentum_ball1_z"])
    F_max, impulse = float(force.max()), float(np.sum(force) * dt)
    return {"t_c": t_c, "F_max": F_max, "impulse": impulse, "hertz_t_c": ref["t_c"], "hertz_F_max": ref["F_max"],
            "rebound": rebound, "err_t_c": t_c / ref["t_c"] - 1.0, "err_F_max": F_max / ref["F_max"] - 1.0,
            "err_impulse": impulse / rebound - 1.0,
            "momentum_drift": float(np.max(np.abs(P - P[0])) / abs(p1[0])),
            "energy_drift": float(np.max(np.abs(e / e[0] - 1.0))),
            "ball1_keeps": float(p1[-1] / p1[0]), "touch": touch, "masses": [par["mass1"], par["mass2"]],
            "t": [float(x) for x in np.asarray(ts["t"]) - touch], "force": [float(f) for f in force],
            "momentum": {b: [float(x) for x in ts[f"momentum_{b}_z"]] for b in ("ball1", "ball2")},
            "velocities": [-par["v"], par["v2"]],
            "hertz": {k: float(ref[k]) for k in ("t_c", "F_max", "delta_max")}}


HEADER = ("case", "level", "dt (s)", "dofs", "t_c (ms)", "Hertz t_c (ms)", "err t_c", "F_max (N)", "Hertz F_max (N)",
          "err F_max", "impulse / 2 m* v", "momentum drift", "energy drift")


def table_rows(rows):
    """The table's rows (strings, :data:`HEADER`'s columns)."""
    return [[r["case"], str(r["level"]), f"{r['dt']:g}", str(r["dofs"]), f"{1e3 * r['t_c']:.3f}",
             f"{1e3 * r['hertz_t_c']:.3f}", f"{100 * r['err_t_c']:+.1f} %", f"{r['F_max']:.4f}",
             f"{r['hertz_F_max']:.4f}", f"{100 * r['err_F_max']:+.1f} %", f"{1 + r['err_impulse']:.4f}",
             f"{r['momentum_drift']:.1e}", f"{100 * r['energy_drift']:.2f} %"] for r in rows]


def plot(rows, path):
    """F(t) of every row against Hertz's, one panel per case (rank 0); returns the file's name."""
    from sdm_dolfinx.study.plotting import COLOURS, pyplot, save
    plt = pyplot()
    cases = list(dict.fromkeys(r["case"] for r in rows))
    fig, axes = plt.subplots(1, len(cases), figsize=(6 * len(cases), 4.2), squeeze=False)
    for ax, case in zip(axes[0], cases):
        mine = [r for r in rows if r["case"] == case]
        ref = mine[0]["hertz"]
        th = np.linspace(0.0, ref["t_c"], 400)
        ax.plot(1e3 * th, hertz_history(ref, th)[1], color="k", ls="--", lw=1.2, label="Hertz")
        for k, r in enumerate(mine):
            ax.plot(1e3 * np.asarray(r["t"]), r["force"], color=COLOURS[k % len(COLOURS)], lw=1.4,
                    label=f"level {r['level']}, dt = {r['dt']:g} s ({r['dofs']} dofs)")
        ax.set_title(f"two balls, {case}: F_max {ref['F_max']:.3f} N, t_c {1e3 * ref['t_c']:.2f} ms (Hertz)",
                     fontsize=9)
        ax.set_xlabel("t after the touch (ms)")
        ax.set_ylabel("contact force (N)")
        ax.set_xlim(-0.2, 1e3 * ref["t_c"] * 1.25)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    return save(fig, path)
