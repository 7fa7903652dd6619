# # A soft ball bouncing fast: finite strain with the singular mass
#
# This demo drops the 3-D rubber ball (the built-in `ball`: R = 20 mm, E = 10 N/mm², ν = 0.3,
# ρ = 1000 kg/m³) onto the rigid plane fast enough that its indentation is of the order of a tenth
# of its radius, with a hyperelastic material, and shows how to
#
# * choose the material and the tangent of the step: `material="neo-hookean"`, `newton="modified"`
#   (run options: `--material`, `--newton` on the command line; docs/finite_strain.md);
# * check what the energy–momentum midpoint scheme promises through the contact, step by step, from an
#   `observe` callback: the energy balance J^{n+1} − J^n = λ · (U^{n+1} − U^n) and the momentum balance
#   p^{n+1} − p^n = dt Σλ (no gravity), both to the tolerance of the step's Newton iterations;
# * compare the contact force with the linear model's and with Hertz's quasi-static theory, which both
#   assume small strains.
#
# Run it with `python demos/rubber_ball.py [--speed 3000] [--out DIR]` (about 15 s; `mpirun -n 2`
# works). With the `CI` variable set the run is cut after the peak force.
#
# ## The runs
#
# At v = 3 m/s Hertz gives an approach δ_max = 2.1 mm (R/10) and a contact time of 2.0 ms. Both the
# neo-Hookean and the linear ball are run at level 1 (6.6k P2 dofs, P2/P1), dt = t_c / 40, from
# 0.01 mm above the plane to 1.1 contact times after the touch.

import argparse
import os
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import simulate
from sdm_dolfinx.problems import ball
from sdm_dolfinx.study.plotting import COLOURS, pyplot, save
from sdm_dolfinx.validation import hertz

COMM = MPI.COMM_WORLD


class Balance:
    """An observe callback: after every step, J^{n+1} - J^n - lam . (U^{n+1} - U^n) is left to compare with
    the time series' energy; it keeps lam . dU per step (collective sums)."""

    def __init__(self):
        self.Uc, self.work = None, [0.0]

    def __call__(self, state):
        d = state.discretisation
        Uc = np.array(state.U[d.cdofs])
        if self.Uc is not None:
            self.work.append(COMM.allreduce(float(np.dot(state.lam, Uc - self.Uc)), op=MPI.SUM))
        self.Uc = Uc


def run(material, speed, level, dt, T, newton="modified"):
    """The time series of one bounce, and the balances' step-by-step residuals."""
    balance = Balance()
    t0 = time.perf_counter()
    r = simulate("ball", {"level": level, "v": speed}, material=material, newton=newton if material != "linear"
                 else None, dt=dt, T=T, observe=balance)
    ts = r.timeseries
    E, p, F = ts["energy"], ts["momentum_y"], ts["contact_force"]
    energy_gap = np.diff(E) - np.asarray(balance.work[1:])       # J^{n+1} - J^n - lam . dU
    momentum_gap = np.diff(p) - dt * F[1:]                         # p^{n+1} - p^n - dt sum(lam)
    return {"material": material, "ts": ts, "seconds": time.perf_counter() - t0,
            "energy_gap": float(np.max(np.abs(energy_gap)) / E[0]),
            "momentum_gap": float(np.max(np.abs(momentum_gap)) / abs(p[0])),
            "F_max": float(F.max()), "E_change": float((E[-1] - E[0]) / E[0])}


# ## The figure
#
# The contact force of both materials against Hertz's F(t), the time counted from the touch.


def plot(rows, ref, speed, path):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.2))
    t = np.linspace(0.0, 1.1 * ref["t_c"], 400)
    ax.plot(1e3 * t, hertz.hertz_history(ref, t)[1], "k", lw=1.8, label="Hertz (quasi-static, small strain)")
    for k, r in enumerate(rows):
        ts = r["ts"]
        first = int(np.flatnonzero(ts["contact_force"] > 0)[0])
        tt = 1e3 * (ts["t"] - ts["t"][first - 1])
        ax.plot(tt, ts["contact_force"], color=COLOURS[k], lw=1.3, label=f"{r['material']}")
    ax.set_xlabel("t after the touch (ms)")
    ax.set_ylabel("contact force (N)")
    ax.set_title(f"rubber ball at {speed / 1000:g} m/s, delta_max / R = {ref['delta_max'] / 20:.2f}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save(fig, path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="A soft ball bouncing fast: finite strain with the singular mass")
    parser.add_argument("--speed", type=float, default=3000.0, help="impact speed (mm/s, default 3000)")
    parser.add_argument("--level", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "output" / "rubber_ball")
    args = parser.parse_args()
    if COMM.rank == 0:
        args.out.mkdir(parents=True, exist_ok=True)
    ref = ball.hertz(v=args.speed)
    dt = ref["t_c"] / 40
    T = (0.6 if os.environ.get("CI") else 1.1) * ref["t_c"] + 0.01 / args.speed
    T = round(T / dt) * dt
    rows = [run(m, args.speed, args.level, dt, T) for m in ("neo-hookean", "linear")]
    if COMM.rank == 0:
        print(f"Hertz at {args.speed:g} mm/s: t_c = {1e3 * ref['t_c']:.3f} ms, F_max = {ref['F_max']:.3f} N, "
              f"delta_max = {ref['delta_max']:.3f} mm (R/{20 / ref['delta_max']:.1f})")
        for r in rows:
            print(f"{r['material']}: F_max = {r['F_max']:.3f} N ({100 * (r['F_max'] / ref['F_max'] - 1):+.1f} % "
                  f"against Hertz), energy balance to {r['energy_gap']:.1e} of E0, momentum balance to "
                  f"{r['momentum_gap']:.1e} of p0, energy change {100 * r['E_change']:+.2f} %, {r['seconds']:.0f} s")
        print("wrote", args.out / plot(rows, ref, args.speed, args.out / "rubber_ball.png"))

    # ## What the runs show
    #
    # In both runs every step satisfies the scheme's energy identity and the momentum balance with the
    # contact impulse to the tolerance of its solves (asserted: 1e-8 of E0 and of p0; measured 2.4e-11 and
    # 3.1e-11 for the neo-Hookean ball, 2e-14 and 7e-15 for the linear one). The energy itself changes by
    # lam . (U^{n+1} - U^n): at vertices arriving on the plane, and at vertices that dipped below it (the
    # midpoint rule's U^{n+1} = 2 X - U^n) when they are pushed back (measured +0.27 % over the bounce for
    # the neo-Hookean ball, +0.23 % for the linear one). At R/10 the two materials' peak forces differ by
    # 0.5 % (201.6 against 200.5 N): the contact force is set by strains of order a/R at the contact, where
    # the neo-Hookean law is still close to Hooke's. Both are 7 % above Hertz's quasi-static small-strain
    # force (-2.9 % at 0.1 m/s on the same mesh): the departure from Hertz as the speed grows, which the
    # report's speed sweep is to follow at finer levels.
    for r in rows:
        assert r["energy_gap"] < 1e-8, f"{r['material']}: energy identity off by {r['energy_gap']:.2e} of E0"
        assert r["momentum_gap"] < 1e-8, f"{r['material']}: momentum balance off by {r['momentum_gap']:.2e} of p0"
        assert r["F_max"] > 0.5 * ref["F_max"], f"{r['material']}: F_max {r['F_max']:.3f} N"
    if COMM.rank == 0:
        print("checked: the energy identity and the momentum balance with the contact impulse at every step, "
              "for the neo-Hookean and the linear ball")
