# # Friction: a block sliding to a stop, and a disc's oblique impact (Coulomb's law)
#
# This demo runs two problems with Coulomb friction at the contact vertices and checks each
# against what a rigid body would do. It shows how to
#
# * switch friction on for any problem (the run options `friction="coulomb"` and `mu`; on the
#   command line `python -m sdm_dolfinx block --friction coulomb --mu 0.3`);
# * read the frictional outputs: the momentum, the friction force Σλ_T, and the stick and slip
#   status of every contact vertex (`contact_status` in `solution.xdmf`);
# * check a frictional run against closed forms and against Coulomb's cone.
#
# Run it with `python demos/friction.py [--out DIR]`; `mpirun -n 2` works too. It takes about
# 10 s on one rank. With the `CI` variable set the block stops at T = 0.036 s (just after its
# stop). The friction law and its step are described in `docs/friction.md`, the closed forms
# derived in `docs/friction_problems.md`.

import argparse
import os
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import simulate
from sdm_dolfinx.problems import block, disc

COMM = MPI.COMM_WORLD
MU_BLOCK = 0.3
VX0 = 1000.0
MU_IMPACT = {"sticking": 1.0, "sliding": 0.1}


def say(*args):
    if COMM.rank == 0:
        print(*args, flush=True)


# ## The sliding block
#
# `block` is a 20 × 10 mm elastic block resting on the foundation in static equilibrium,
# launched sideways at v0 = 100 mm/s. A rigid block with Coulomb friction μ decelerates at μ g
# and stops at t* = v0 / (μ g) = 34.0 ms (`block.stopping` computes both). We measure the
# deceleration as the slope of a line fitted to the velocity P_x / m while 10 % < v / v0 < 90 %,
# and the stop as the first zero of the velocity (interpolated within its step).


def sliding_block(mu=MU_BLOCK, T=0.04):
    """The block's time series, its measured deceleration and stop time, and the rigid block's."""
    p = block.problem()
    m = block.total_mass(p)
    prm = p.parameters
    ts = simulate(p, pair="P2/P1", dt=1e-4, T=T, friction="coulomb", friction_options={"mu": mu}).timeseries
    t, v = ts["t"], ts["momentum_x"] / m
    a_cf, t_cf, d_cf = block.stopping(prm["v0"], prm["gravity"], m, prm["width"], mu=mu)
    sel = (v > 0.1 * prm["v0"]) & (v < 0.9 * prm["v0"])
    k = int(np.argmax(v <= 0.0))                          # the first step at rest (or moving back)
    t_stop = t[k - 1] + (t[k] - t[k - 1]) * v[k - 1] / (v[k - 1] - v[k]) if v[k] <= 0.0 else np.nan
    return {"ts": ts, "m": m, "g": prm["gravity"], "v0": prm["v0"], "dt": 1e-4,
            "a": -np.polyfit(t[sel], v[sel], 1)[0], "t_stop": t_stop, "a_closed": a_cf, "t_stop_closed": t_cf}


# ## The disc's oblique impact
#
# The paper's disc (level 1) falls at v0 = −1000 mm/s with a horizontal velocity
# vx0 = 1000 mm/s. Rigid-body impact theory: while the disc slides, friction takes exactly
# μ J_N of its horizontal momentum per unit mass, J_N being the normal impulse (read from the
# vertical momentum balance); it slides through the whole impact when μ < vx0 m / (3 J_N) ≈ 0.15.
# So with μ = 0.1 the horizontal velocity must drop by exactly μ J_N / m; with μ = 1 the
# contact sticks. `simulate` runs the registered problem with `out=` and `write_every=1`, so
# that every step's `contact_status` can be read back from `solution.xdmf`.


def oblique_impact(mu, out, level=1, dt=1e-4, T=0.017):
    """The disc with vx0 = VX0 and Coulomb ``mu``: the time series, the normal impulse J_N / m
    and the change of horizontal velocity."""
    r = simulate("disc", {"level": level, "vx0": VX0}, out=out, overwrite=True, pair="P2/P1", dt=dt, T=T,
                 friction="coulomb", friction_options={"mu": mu}, write_every=1)
    ts = r.timeseries
    m = disc.total_mass(r.discretisation.problem)
    g = r.discretisation.problem.parameters["gravity"]
    jn = (ts["momentum_y"][-1] - ts["momentum_y"][0]) / m + g * ts["t"][-1]    # the momentum balance
    stick, slip = ts["n_stick"].sum(), ts["n_slip"].sum()
    on = ts["n_active"] > 0
    return {"ts": ts, "mu": mu, "jn": jn, "dvx": (ts["momentum_x"][-1] - ts["momentum_x"][0]) / m,
            "stick_fraction": stick / max(stick + slip, 1.0), "folder": Path(out),
            "cone": float(np.max(np.abs(ts["tangential_force"][on]) / (mu * ts["contact_force"][on])))}


def contact_zones(folder):
    """Rank 0: (times, x positions, status) of the vertices that touch at some stored time,
    read back from the run's solution.xdmf (status: 0 free, 1 stick, 2 slip)."""
    from sdm_dolfinx.io.xdmf_reader import read_xdmf
    s = read_xdmf(folder)
    verts = np.flatnonzero(s.vertex_mask())
    status = np.array([s.field("contact_status", t)[verts] for t in s.times]).astype(int)
    touch = verts[np.any(status > 0, axis=0)]
    x = np.array([s.points[touch, 0] + s.field("displacement", t)[touch, 0] for t in s.times])
    return np.asarray(s.times), x, status[:, np.any(status > 0, axis=0)]


# ## Figures
#
# The block's velocity against v0 − μ g t and its forces against the rigid block's; for the
# impact, the friction force inside Coulomb's cone ±μ Σλ_N, and the stick (blue) and slip
# (red) vertices along the foundation over the contact phase.


def plot_block(b, png):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ts = b["ts"]
    t = 1e3 * ts["t"]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.4))
    axes[0].plot(t, ts["momentum_x"] / b["m"], lw=2, label=f"ours (mu = {MU_BLOCK:g})")
    axes[0].plot(t, np.maximum(b["v0"] - b["a_closed"] * ts["t"], 0.0), "k:", label="rigid block: v0 - mu g t")
    axes[0].set(xlabel="t (ms)", ylabel="velocity P$_x$ / m (mm/s)", title="velocity")
    axes[1].plot(t[1:], ts["contact_force"][1:] / (b["m"] * b["g"]), label="normal force / m g")
    axes[1].plot(t[1:], -ts["tangential_force"][1:] / (MU_BLOCK * b["m"] * b["g"]),
                 label="-friction force / mu m g (= normal / m g while it slides)")
    axes[1].set(xlabel="t (ms)", ylabel="force / rigid-block value", title="forces on the bottom")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle("Elastic block sliding to a stop, Coulomb friction, P2/P1, midpoint, dt = 1e-4 s")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def plot_impact(runs, zones, png):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, len(runs), figsize=(6.5 * len(runs), 8), sharex=True)
    for col, (case, r) in enumerate(runs.items()):
        ts = r["ts"]
        t, on = 1e3 * ts["t"], ts["n_active"] > 0
        span = (t[on][0] - 0.3, t[on][-1] + 0.3)
        cone = r["mu"] * ts["contact_force"]
        ax = axes[0, col]
        ax.fill_between(t, -cone, cone, color="0.85", label="Coulomb's cone ±mu Σλ$_N$")
        ax.plot(t, ts["tangential_force"], color="tab:purple", label="friction force Σλ$_T$")
        ax.set(ylabel="force (N per mm)", title=f"{case}: mu = {r['mu']:g}", xlim=span)
        times, x, status = zones[case]
        ax = axes[1, col]
        for code, name, colour in ((1, "stick", "tab:blue"), (2, "slip", "tab:red")):
            i, j = np.nonzero(status == code)
            ax.scatter(1e3 * times[i], x[i, j], s=14, marker="s", color=colour, lw=0, label=name)
        ax.set(xlabel="t (ms)", ylabel="position along the foundation x + u$_x$ (mm)", title="contact vertices")
        for ax in axes[:, col]:
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8, loc="lower left")
    fig.suptitle(f"Oblique impact of the disc (vx0 = {VX0:g} mm/s, v0 = -1000 mm/s), level 1, P2/P1, midpoint, "
                 "dt = 1e-4 s")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


# ## Running the demo

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="Friction: a block sliding to a stop, and a disc's oblique impact")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "output" / "friction")
    args = parser.parse_args()
    if COMM.rank == 0:
        args.out.mkdir(parents=True, exist_ok=True)
    COMM.Barrier()

    b = sliding_block(T=0.036 if os.environ.get("CI") else 0.04)
    say(f"block, Coulomb mu = {MU_BLOCK:g}: deceleration {b['a']:.1f} mm/s^2 (rigid block mu g = {b['a_closed']:.1f}, "
        f"{b['a'] / b['a_closed'] - 1:+.2e}); stops at {1e3 * b['t_stop']:.2f} ms (v0 / (mu g) = "
        f"{1e3 * b['t_stop_closed']:.2f} ms, {b['t_stop'] / b['t_stop_closed'] - 1:+.2%})")

    runs = {case: oblique_impact(mu, args.out / f"impact_mu{mu:g}") for case, mu in MU_IMPACT.items()}
    for case, r in runs.items():
        say(f"impact, mu = {r['mu']:g} ({case}): J_N / m = {r['jn']:.0f} mm/s, dvx = {r['dvx']:.1f} mm/s "
            f"(sliding throughout: -mu J_N / m = {-r['mu'] * r['jn']:.1f}; rigid disc ending in rolling: "
            f"{-VX0 / 3:.1f}); {r['stick_fraction']:.0%} of the contact vertex-steps stick; "
            f"max |sum lam_T| / (mu sum lam_N) = {r['cone']:.6f}")

    if COMM.rank == 0:
        plot_block(b, args.out / "friction_block.png")
        zones = {case: contact_zones(r["folder"]) for case, r in runs.items()}
        plot_impact(runs, zones, args.out / "friction_impact.png")
        print(f"wrote {args.out / 'friction_block.png'} and {args.out / 'friction_impact.png'}")

    # ## What the runs show
    #
    # The elastic block decelerates as the rigid one, μ g, to 1e-4 relative (measured 6e-6),
    # and stops within two time steps of v0 / (μ g) (measured one step late: 34.08 ms).
    assert abs(b["a"] / b["a_closed"] - 1.0) < 1e-4, b["a"]
    assert abs(b["t_stop"] - b["t_stop_closed"]) <= 2 * b["dt"], b["t_stop"]
    # The friction force never leaves Coulomb's cone: |Σλ_T| ≤ μ Σλ_N at every contact step.
    for case, r in runs.items():
        assert r["cone"] <= 1.0 + 1e-9, f"{case}: |sum lam_T| / (mu sum lam_N) = {r['cone']}"
    # With μ = 0.1 the disc slides through the whole impact, and its horizontal velocity drops
    # by exactly μ J_N / m (measured to 3e-12 relative); with μ = 1 most contact vertex-steps
    # stick (measured 88 %).
    sliding, sticking = runs["sliding"], runs["sticking"]
    assert sliding["stick_fraction"] == 0.0, sliding["stick_fraction"]
    assert abs(sliding["dvx"] + sliding["mu"] * sliding["jn"]) <= 1e-8 * sliding["mu"] * sliding["jn"], sliding["dvx"]
    assert sticking["stick_fraction"] > 0.5, sticking["stick_fraction"]
    say("checked: deceleration mu g, the stop at v0 / (mu g), Coulomb's cone, and the sliding impact's "
        "dvx = -mu J_N / m")
