# # Two elastic balls colliding, against Hertz
#
# This demo runs contact between two deformable 3-D bodies with the singular dynamic method and
# checks it against Hertz's theory of two elastic spheres. It shows how to
#
# * run a problem with several bodies and a contact pair (the built-in `two_balls`,
#   `sdm_dolfinx/problems/two_balls.py`: one mesh
#   of two balls, a `ContactPair` of ball 1's lower hemisphere on ball 2's upper one, `Body` columns);
# * compare the contact force with Hertz's F(t) for the reduced radius, modulus and mass
#   (`sdm_dolfinx.problems.two_balls.hertz_two`; the runs and their numbers are
#   `sdm_dolfinx.validation.two_balls`'s, which the report's section "two balls against Hertz" runs too);
# * follow the momentum each ball carries through the impact (the per-body columns).
#
# Run it with `python demos/two_balls.py [--level 1] [--out DIR]`; `mpirun -n 2` works too
# (about 40 s in all at level 1).
#
# ## The runs
#
# * Head on: two equal balls (R = 20 mm, E = 10 N/mm², ν = 0.3, ρ = 1000 kg/m³) at ±0.1 m/s. Hertz:
#   F_max = 3.161 N, t_c = 3.90 ms, as the single ball on a rigid plane at 0.1 m/s.
# * Unequal: ball 2 with R2 = 10 mm, E2 = 40 N/mm², ρ2 = 3000 kg/m³, at rest, struck by ball 1 at
#   0.1 m/s. Hertz: F_max = 1.064 N, t_c = 3.16 ms; a rigid elastic collision leaves ball 1 with
#   (m1 − m2)/(m1 + m2) = 45 % of its momentum and gives ball 2 the rest.
#
# Both with P2/P1 and the midpoint scheme. It writes `two_balls_hertz.png` into
# `demos/output/two_balls/` (or `--out`).

import argparse
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.study.plotting import COLOURS, pyplot, save
from sdm_dolfinx.validation import two_balls

COMM = MPI.COMM_WORLD
HERE = Path(__file__).resolve().parent


# ## The figure
#
# Left: the contact force against Hertz's F(t) for each run (`two_balls.plot` draws one panel per case).
# Right: each ball's momentum along z over the size of ball 1's initial one (the per-body columns), with a
# rigid elastic collision's final values dashed.


def plot(rows, path, level):
    from sdm_dolfinx.validation.hertz import hertz_history
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    for k, r in enumerate(rows):
        c, t = COLOURS[k % len(COLOURS)], 1e3 * np.asarray(r["t"])
        th = np.linspace(0.0, r["hertz"]["t_c"], 400)
        axes[0].plot(1e3 * th, hertz_history(r["hertz"], th)[1], color=c, ls="--", lw=1.2, label=f"Hertz, {r['case']}")
        axes[0].plot(t, r["force"], color=c, lw=1.5, label=f"P2/P1, {r['case']}")
        P0 = abs(r["momentum"]["ball1"][0])
        (m1, m2), (v1, v2) = r["masses"], r["velocities"]                   # the velocities along z
        rigid = {"ball1": m1 * ((m1 - m2) * v1 + 2.0 * m2 * v2) / (m1 + m2),
                 "ball2": m2 * ((m2 - m1) * v2 + 2.0 * m1 * v1) / (m1 + m2)}
        for b, ls in (("ball1", "-"), ("ball2", ":")):
            axes[1].plot(t, np.asarray(r["momentum"][b]) / P0, color=c, ls=ls, label=f"{b}, {r['case']}")
            axes[1].axhline(rigid[b] / P0, color=c, ls="--", lw=0.6)
    axes[0].set_ylabel("contact force (N)")
    axes[1].set_ylabel("momentum along z / |ball 1's initial|")
    for ax in axes:
        ax.set_xlabel("t after the touch (ms)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"two elastic balls, level {level}, P2/P1, midpoint scheme")
    fig.tight_layout()
    return save(fig, path)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="Two elastic balls colliding, against Hertz")
    parser.add_argument("--level", type=int, default=1, help="mesh level of each ball (default 1)")
    parser.add_argument("--out", type=Path, default=HERE / "output" / "two_balls")
    args = parser.parse_args()
    if COMM.rank == 0:
        args.out.mkdir(parents=True, exist_ok=True)
    rows = [two_balls.run_one(case, args.level) for case in two_balls.CASES]
    # ## What the runs show
    #
    # At level 1 (two cells across the contact radius) the peak force is within 5 % of Hertz's
    # (measured -2.7 % head on, -3.2 % unequal) and the impulse within 1 % of 2 m* v, a full elastic
    # rebound of the relative motion (measured 0.2 %, 0.07 %); the total momentum is constant to round-off
    # (the contact forces are equal and opposite) and the energy within 0.5 %.
    for r in rows:
        label = r["case"]
        if COMM.rank == 0:
            print(f"{label}: F_max = {r['F_max']:.4f} N (Hertz {r['hertz_F_max']:.4f}, {100 * r['err_F_max']:+.1f} %), "
                  f"impulse / 2 m* v = {1 + r['err_impulse']:.4f}, largest energy deviation "
                  f"{100 * r['energy_drift']:.2f} %, ball 1 keeps {r['ball1_keeps']:.3f} of its momentum")
        assert abs(r["err_F_max"]) < 0.05, f"{label}: F_max {r['err_F_max']:+.1%} against Hertz"
        assert abs(r["err_impulse"]) < 0.01, f"{label}: impulse {1 + r['err_impulse']:.4f} of 2 m* v"
        assert r["momentum_drift"] <= 1e-10, f"{label}: momentum"
        assert r["energy_drift"] < 0.005, f"{label}: energy"
    if COMM.rank == 0:
        print("wrote", args.out / plot(rows, args.out / "two_balls_hertz.png", args.level))
        print("checked: the peak force against Hertz for two spheres, the impulse of a full rebound, the momentum "
              "and the energy")
