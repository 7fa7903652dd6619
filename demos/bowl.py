# # A disc sliding in a rigid circular bowl: a curved obstacle against the pendulum
#
# This demo runs a problem whose obstacle is curved, declared as a signed distance
# (`demos/bowl_problem.py`: `obstacles=[Ball(centre, Rb, inside=True)]`, no `lower_bound`), and
# checks its motion against a closed form. It shows how to
#
# * pose contact with a rigid obstacle of any shape (sdm_dolfinx.obstacles) in a problem file;
# * read the rigid motion of a body from the momentum columns (`momentum_x` = e_xᵀ M V̄: the mass
#   times the velocity of the centre of mass);
# * check the energy of a run that slides on a curved obstacle for a whole period.
#
# Run it with `python demos/bowl.py [--out DIR] [--rolling]`; `mpirun -n 2` works too (about 12 s on
# one rank, measured; `--rolling` adds a rolling study of about 30 s, at the end). With the `CI`
# variable set the runs take twice the time step.
#
# ## The problem
#
# A plane-strain elastic disc (r = 10 mm, E = 1000 N/mm², ν = 0.3, ρ = 1e-6 t/mm³) starts at
# rest, unstressed, in a rigid circular bowl of radius Rb = 40 mm, touching it at θ0 = 11.5° from
# the bottom; gravity g = 9810 mm/s² pulls it down and the contact is frictionless. The contact
# force is normal to the bowl, so it passes through the disc's centre: the disc does not turn, and
# its centre moves on the circle of radius L = Rb − r. It is a pendulum of length L:
#
#     T0 = 2π √(L / g)  (small angles),   T(θ0) = T0 · 2 K(sin(θ0/2)) / π  (amplitude θ0, exactly),
#
# K the complete elliptic integral of the first kind (T(11.5°) = 1.0025 T0). Every boundary
# vertex of the disc is constrained; the gap rows are linearised at the current configuration
# every step, so the contact point moves around the disc as it swings (with the bowl's normal of
# the start kept, there would be no restoring force at all). The disc's wave transit 2r/c_p is
# 1/500 of the period: it swings as a rigid body on a thin elastic contact layer.
#
# We run the singular dynamic method with the midpoint scheme, dt = T0/2000 over 2.2 periods:
#
# * P1+/P0, contact at the vertices;
# * P2/P1 with `constrain="nodes"`: every P2 node of the disc's boundary holds the constraint.
#
# It writes into `demos/output/bowl/` (or `--out`): `bowl.png` (the angle of the disc's centre
# against the pendulum's, and the energy over the kinetic energy's largest value) and the runs'
# folders (`timeseries.csv`, `solution.xdmf` every 20 steps, `obstacles.xdmf`: the bowl for ParaView).

import argparse
import os
import sys
from pathlib import Path

from mpi4py import MPI

import numpy as np
from scipy.special import ellipk

from sdm_dolfinx import simulate
from sdm_dolfinx.problems import load_file
from sdm_dolfinx.study.plotting import COLOURS, pyplot, save

COMM = MPI.COMM_WORLD
PROBLEM_FILE = Path(__file__).resolve().parent / "bowl_problem.py"
BOWL = sys.modules[load_file(PROBLEM_FILE).build.__module__]
#: the disc and the bowl (the problem file's defaults, given explicitly: the checks depend on them)
VALUES = {"r": 10.0, "Rb": 40.0, "E": 1000.0, "nu": 0.3, "rho": 1e-6, "gravity": 9810.0, "theta0": 11.5, "h": 1.0}
RUNS = (("P1+/P0", "vertices"), ("P2/P1", "nodes"))
#: the checks: the measured period within PERIOD_RTOL of T(theta0); the energy within ENERGY_RTOL of its
#: start, relative to the largest kinetic energy, at dt = T0/2000 (it grows O(dt): see below; the bound
#: scales with dt)
PERIOD_RTOL, ENERGY_RTOL = 0.01, 0.05


def say(*args):
    if COMM.rank == 0:
        print(*args, flush=True)


def pendulum_period(theta0):
    """T(theta0) / T0 = 2 K(sin(theta0 / 2)) / pi (scipy's ellipk takes m = k^2)."""
    return 2.0 * ellipk(np.sin(0.5 * theta0) ** 2) / np.pi


# ## Measuring the swing
#
# `momentum_x` / m is the x-velocity of the disc's centre of mass; its upward zero crossings
# (interpolated linearly between steps) are one period apart. The centre's x is its integral
# (trapezoidal rule) from x0 = L sin θ0, and its angle from the bowl's axis is asin(x / L).


def run(pair, constrain, dt, T, out):
    r = simulate(PROBLEM_FILE, VALUES, pair=pair, constrain=constrain, dt=dt, T=T, out=out, overwrite=True,
                 write_every=20)
    ts = r.timeseries
    t, px = np.asarray(ts["t"]), np.asarray(ts["momentum_x"])
    up = np.flatnonzero((px[:-1] < 0) & (px[1:] >= 0))
    crossings = t[up] + (t[up + 1] - t[up]) * px[up] / (px[up] - px[up + 1])
    say(f"{pair}, constrain {constrain}: {r.info['steps']} steps, {r.info['wall_time']:.1f} s")
    return {"pair": pair, "constrain": constrain, "ts": ts, "crossings": crossings}


def plot(results, T0, Tex, L, theta0, path):
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    mass = VALUES["rho"] * np.pi * VALUES["r"] ** 2
    for k, res in enumerate(results):
        ts, c = res["ts"], COLOURS[k]
        t = np.asarray(ts["t"])
        v = np.asarray(ts["momentum_x"]) / mass
        x = L * np.sin(theta0) + np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
        label = f"{res['pair']}, constrain {res['constrain']}"
        axes[0].plot(t / T0, np.degrees(np.arcsin(np.clip(x / L, -1, 1))), color=c, lw=1.5, label=label)
        E = np.asarray(ts["energy"])
        axes[1].plot(t / T0, (E - E[0]) / np.max(ts["kinetic"]), color=c, label=label)
    s = np.linspace(0.0, results[0]["ts"]["t"][-1] / T0, 600)
    axes[0].plot(s, np.degrees(theta0) * np.cos(2 * np.pi * s * T0 / Tex), "k--", lw=1,
                 label=f"pendulum, period T($\\theta_0$) = {Tex / T0:.4f} T0 (its first harmonic)")
    axes[0].set_xlabel("t / T0,  T0 = 2$\\pi\\sqrt{(R_b - r)/g}$")
    axes[0].set_ylabel("angle of the disc's centre from the bowl's axis (degrees)")
    axes[0].set_title("the swing")
    axes[1].set_xlabel("t / T0")
    axes[1].set_ylabel("(E - E(0)) / max kinetic energy")
    axes[1].set_title("energy (midpoint scheme: conserved without impact)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"Elastic disc (r = {VALUES['r']:g} mm) sliding in a rigid bowl (R$_b$ = {VALUES['Rb']:g} mm), "
                 f"frictionless, plane strain")
    fig.tight_layout()
    return save(fig, path)


# ## Rolling (`--rolling`): what the linear model can and cannot do
#
# With Coulomb friction (μ = 0.5) the disc rolls instead of sliding. A rigid disc rolling in the bowl
# swings with the period √(3/2) T0 (its rotational inertia adds half its mass). The linear model gives
# another one, and the reason is the model, not the contact: its rotation field u = ω × x is strain-free
# but moves the boundary to the radius r √(1 + ω²), so the disc turned by ω stands r ω²/2 higher in the
# bowl, a potential m g r ω²/2 of the same order as the pendulum's m g L θ²/2 (rolling turns the disc by
# ω = L θ / r). With it the small-oscillation period is
#
#     T_lin = 2π √(3 L / (2 g (1 + L/r)))   (= 0.612 T0 at L/r = 3),
#
# which the study checks within ROLL_RTOL at θ0 = 1° on a boundary fine enough for the contact to roll
# over many vertices (h = 0.25 mm; about 30 s on one rank). Measured: 0.6148 T0, +0.4 %. (The swings
# after it lengthen: the energy grows by some 70 % of the small swing's kinetic energy over two periods,
# the rows' linearisation on the concave bowl as in the sliding runs, here against a kinetic energy
# 100 times smaller.) The rolling period needs finite strain.
ROLL_RTOL = 0.01


def rolling(out):
    r, L, g = VALUES["r"], VALUES["Rb"] - VALUES["r"], VALUES["gravity"]
    T0 = float(BOWL.period(r, VALUES["Rb"], g))
    T_lin = 2 * np.pi * np.sqrt(3 * L / (2 * g * (1 + L / r)))
    res = simulate(PROBLEM_FILE, {**VALUES, "theta0": 1.0, "h": 0.25}, pair="P1+/P0", dt=T0 / 2000, T=1.3 * T0,
                   friction="coulomb", friction_options={"mu": 0.5}, out=out, overwrite=True, write_every=50)
    ts = res.timeseries
    t, px = np.asarray(ts["t"]), np.asarray(ts["momentum_x"])
    up = np.flatnonzero((px[:-1] < 0) & (px[1:] >= 0))
    tc = t[up] + (t[up + 1] - t[up]) * px[up] / (px[up] - px[up + 1])
    period = float(tc[1] - tc[0])          # the first full swing, as above
    say(f"rolling (mu = 0.5, theta0 = 1 deg, h = 0.25 mm): period {period / T0:.4f} T0; the linear model's "
        f"closed form {T_lin / T0:.4f} T0 ({period / T_lin - 1:+.2%}), the rigid disc's {np.sqrt(1.5):.4f} T0; "
        f"{res.info['wall_time']:.0f} s")
    assert abs(period / T_lin - 1) <= ROLL_RTOL, f"rolling: the period is off the linear model's by {period / T_lin - 1:+.2%}"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="An elastic disc sliding in a rigid circular bowl, against the "
                                                 "pendulum's period")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "output" / "bowl")
    parser.add_argument("--rolling", action="store_true",
                        help="also the rolling disc (Coulomb mu = 0.5) against the linear model's period (~30 s)")
    args = parser.parse_args()
    if COMM.rank == 0:
        args.out.mkdir(parents=True, exist_ok=True)
    L, theta0 = VALUES["Rb"] - VALUES["r"], np.radians(VALUES["theta0"])
    T0 = float(BOWL.period(VALUES["r"], VALUES["Rb"], VALUES["gravity"]))
    Tex = T0 * pendulum_period(theta0)
    dt = T0 / (1000 if os.environ.get("CI") else 2000)
    results = [run(pair, constrain, dt, 2.2 * T0, args.out / f"bowl_{pair.replace('/', '-')}")
               for pair, constrain in RUNS]
    if COMM.rank == 0:
        say("wrote", args.out / plot(results, T0, Tex, L, theta0, args.out / "bowl.png"))

    # ## What the runs show
    #
    # Measured (dt = T0/2000, one rank): the period within 0.4 % of T(θ0) (P1+/P0: −0.32 %; P2/P1
    # with every node constrained: +0.13 %). The energy is not conserved exactly: it grows by about
    # 1 % of the largest kinetic energy per period (2.3 % over 2.2 periods, P1+/P0), in steps where
    # the disc is fastest. That is the rows' linearisation at the start of each step on a concave
    # obstacle: a node sliding by d along the bowl ends the step O(|d|²/R) inside it (the bowl's
    # circle lies outside its tangent), the next step pushes it back out, and the force does the
    # work λ · O(|d|²/R) > 0 each step: O(dt) per unit time, which vanishes as dt → 0 (measured with
    # tests' settings: 2.9 % at dt = T0/2000, 1.2 % at T0/4000, for E = 1000 N/mm², r = 10 mm; with
    # the CI variable's T0/1000, 6.6 % on dolfinx 0.9): the check's bound is 5 % at T0/2000, scaled
    # with dt.
    for res in results:
        where = f"{res['pair']}, constrain {res['constrain']}"
        tc = res["crossings"]
        assert len(tc) >= 2, f"{where}: fewer than two swings measured"
        period = tc[1] - tc[0]
        E, K = np.asarray(res["ts"]["energy"]), np.max(res["ts"]["kinetic"])
        drift = np.max(np.abs(E - E[0])) / K
        bound = ENERGY_RTOL * dt * 2000 / T0
        say(f"{where}: period {period:.5f} s, T(theta0) {Tex:.5f} s ({period / Tex - 1:+.2%}; small-angle T0 "
            f"{T0:.5f} s), energy within {drift:.1%} of the largest kinetic energy")
        assert abs(period / Tex - 1) <= PERIOD_RTOL, f"{where}: the period is off T(theta0) by {period / Tex - 1:+.2%}"
        assert drift <= bound, f"{where}: the energy moved by {drift:.1%} of the largest kinetic energy"
    say(f"checked: the period within {PERIOD_RTOL:.0%} of the pendulum's, the energy within "
        f"{ENERGY_RTOL * dt * 2000 / T0:.0%} of the largest kinetic energy (O(dt))")
    if args.rolling:
        rolling(args.out / "bowl_rolling")
