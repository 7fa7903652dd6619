# # Displacement-controlled indentation: an elastic disc pressed onto a rigid flat, against Hertz
#
# This demo pushes a body by a prescribed displacement (a `DirichletPart` whose data move) and
# checks the contact zone it makes against Hertz's line-contact law. It shows how to
#
# * run a problem file of one's own (`demos/punch_problem.py`) with prescribed, time-dependent
#   displacements, and read its reaction column `reaction_top_y`;
# * measure the contact zone during the run with an `observe` callback (the nodal contact forces
#   `state.lam` at the constrained nodes `state.discretisation.cx`);
# * check that a slow push is quasi-static (kinetic against elastic energy).
#
# Run it with `python demos/punch.py [--h 0.125] [--out DIR]`; `mpirun -n 2` works too (14 s in all
# on one rank, measured). With the `CI` variable set the runs take twice the time step (9 s).
#
# ## The problem
#
# A plane-strain elastic disc (R = 20 mm, E = 1000 N/mm², ν = 0.3, ρ = 1e-6 t/mm³) rests,
# unstressed, on the frictionless rigid foundation y = 0, touching it at its lowest point A. A
# 30° arc at its top is moved down by d(t) = depth (1 − cos(π t / ramp)) / 2 (held at 0 in x: both
# components are prescribed, so that the disc cannot translate sideways or rotate, which
# frictionless contact alone would not prevent), to depth = 0.6 mm over ramp = 0.2 s, 180 times
# the disc's wave transit 2R/c_p = 1.1 ms: quasi-static. Contact acts at the boundary vertices of
# the lower half circle; the mesh has the size h = 0.125 mm within 2.5 mm of A (the contact
# half-width reaches 2.3 mm).
#
# Hertz's cylinder on a flat with the roles inverted (the cylinder elastic, the flat rigid) gives,
# for a half-width a ≪ R, a² = 4 P R / (π E*), E* = E / (1 − ν²), P the load per mm of thickness
# (the `contact_force` column; quasi-statically −`reaction_top_y`), and the elliptic pressure
# p(x) = (2P / (π a²)) √(a² − x²). The approach d of a 2-D indentation has no closed form of its
# own (a line load's displacement field grows like the logarithm of the distance: d depends on
# the body's size and on how the load is applied), so P(d) is shown as measured.
#
# We run the singular dynamic method with the midpoint scheme twice:
#
# * P1+/P0 (P1 plus cubic bubbles for u, P0 for v), contact at the vertices;
# * P2/P1 with `constrain="nodes"`: every P2 node of the contact boundary holds the constraint.
#   With the default vertex constraint (13) P2's mid-edge nodes are free to sink below the
#   foundation between the constrained vertices (the P2 boundary is not held by its vertices):
#   here, measured, they sink 7.8 µm below it at the final load (against a²/(2R) = 0.13 mm of
#   closure at the zone's edge), with no warning (its threshold, 1e-3 of the boundary's size, is
#   40 µm), which blurs the very zone we measure; constraining every node removes it (the lowest
#   node is then 0.14 µm below: the midpoint scheme's O(dt) dip of U^{n+1}). The pair stays
#   well-posed so (`python -m sdm_dolfinx inspect --problem-file demos/punch_problem.py --pair
#   P2/P1 --constrain nodes`: β = 0.80 in condition (7), 0.90 with the vertices only).
#
# It writes into `demos/output/punch/` (or `--out`): `punch_hertz.png` (the measured half-width
# against Hertz's over the loading, and the contact pressure at the final load against Hertz's
# ellipse), `punch_force.png` (P against d, and the kinetic/elastic energy ratio), and the runs'
# folders `punch_P1+-P0/` and `punch_P2-P1/` (`solution.xdmf` every 20 steps, `timeseries.csv`).

import argparse
import os
import sys
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import simulate
from sdm_dolfinx.problems import load_file
from sdm_dolfinx.study.plotting import COLOURS, pyplot, save

COMM = MPI.COMM_WORLD
PROBLEM_FILE = Path(__file__).resolve().parent / "punch_problem.py"
#: the problem file's module (its closed form and its ramp d(t)), as load_file imported it
PUNCH = sys.modules[load_file(PROBLEM_FILE).build.__module__]
#: the disc and the push (the problem file's defaults, given explicitly: the checks depend on them)
R, E, NU, DEPTH, RAMP = 20.0, 1000.0, 0.3, 0.6, 0.2
#: (pair, constrain) of the runs
RUNS = (("P1+/P0", "vertices"), ("P2/P1", "nodes"))
#: Hertz's check: the loads (as fractions of the final contact force) where a is compared, and
#: the tolerance |a - a_Hertz| <= h / 2 + REL_TOL a_Hertz (h / 2: the measurement's own uncertainty)
FRACTIONS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
REL_TOL = 0.05


def say(*args):
    if COMM.rank == 0:
        print(*args, flush=True)


# ## Measuring the contact zone
#
# After every step the `observe` callback gathers, on rank 0, the x of every constrained node
# and its nodal contact force λ_i ≥ 0 (the midpoint step's multiplier). The contact zone is where
# λ_i > 0. Its edge lies between the outermost node with λ > 0 and the next node outward, which
# is free: we take the half-width a as the midpoint of those two bounds, a_in = half the
# extent of the active nodes and a_out = half the distance between the first free nodes on either
# side, with the uncertainty ±(a_out − a_in)/2, half the node spacing (≈ h/2 at the vertices,
# h/4 at P2's nodes).


class ContactZone:
    """``observe`` callback: per row, (a_in, a_out) of the contact zone (rank 0), and the nodal
    contact pressures λ_i / |Γ_i| of the last row."""

    def __init__(self):
        self.rows = []
        self.last = None

    def __call__(self, state):
        d = state.discretisation
        pieces = COMM.gather((d.cx[0].copy(), np.asarray(state.lam).copy(), np.asarray(d.cmeasure).copy()), root=0)
        if COMM.rank != 0:
            return
        x, lam, meas = (np.concatenate([p[k] for p in pieces]) for k in range(3))
        on = lam > 0.0
        if not on.any():
            self.rows.append((0.0, 0.0))
            return
        left, right = x[on].min(), x[on].max()
        free_left = x[~on & (x < left)].max(initial=-np.inf)
        free_right = x[~on & (x > right)].min(initial=np.inf)
        self.rows.append((0.5 * (right - left), 0.5 * (free_right - free_left)))
        self.last = (x, lam / meas)


def run(pair, constrain, h, dt, out):
    """One run: its time series, the contact zone per row, the final pressures and parameters."""
    zone = ContactZone()
    r = simulate(PROBLEM_FILE, {"h": h, "R": R, "E": E, "nu": NU, "depth": DEPTH, "ramp": RAMP}, pair=pair,
                 constrain=constrain, dt=dt, T=RAMP,
                 observe=zone, out=out, overwrite=True, write_every=20)
    ts = r.timeseries
    say(f"{pair}, constrain {constrain}: {r.info['steps']} steps, {r.info['wall_time']:.1f} s, "
        f"final contact force {ts['contact_force'][-1]:.2f} N/mm")
    return {"pair": pair, "constrain": constrain, "ts": ts, "zone": np.array(zone.rows) if COMM.rank == 0 else None,
            "pressure": zone.last}


# ## The comparison with Hertz
#
# At loads from 10 % to 100 % of the final one (a from 0.7 mm, 6 cells of size h, to
# 2.3 mm, 18 cells; a/R ≤ 0.12) the measured a must lie within h/2 + 5 % of Hertz's (h/2: the
# measurement's own uncertainty). The push must be quasi-static: at those loads the kinetic
# energy is below 1 % of the elastic one, and the contact force and the punch's reaction
# −`reaction_top_y` agree within 1 %.


def push_at_force_time(t):
    """d at the time of each row's contact force and reaction: the midpoint step n-1 -> n puts them
    in row n at t_{n-1/2}, where the scheme's iterate takes the data (d(t_{n-1}) + d(t_n)) / 2."""
    d = PUNCH.push(t, DEPTH, RAMP)
    return np.concatenate([[0.0], 0.5 * (d[1:] + d[:-1])])


def compare(res, h):
    """Rows (d, P, a_in, a_out, a, a_Hertz, kinetic/elastic, |P + R_y| / P, row) at the checked loads."""
    ts, zone = res["ts"], res["zone"]
    P, d = ts["contact_force"], push_at_force_time(ts["t"])
    rows = []
    for f in FRACTIONS:
        n = int(np.argmin(np.abs(P - f * P[-1])))
        a_in, a_out = zone[n]
        rows.append((d[n], P[n], a_in, a_out, 0.5 * (a_in + a_out), PUNCH.hertz_half_width(P[n], R, E, NU),
                     ts["kinetic"][n] / ts["elastic"][n], abs(P[n] + ts["reaction_top_y"][n]) / P[n], n))
    return np.array(rows)


# ## The figures
#
# `punch_hertz.png`: left, the measured half-width (the bar spans a_in to a_out) against Hertz's
# √(4PR/(πE*)) at every step, with the line a = a_Hertz and the tolerance band; right, the nodal
# contact pressures λ_i / |Γ_i| at the final load against Hertz's ellipse for the same P.
# `punch_force.png`: left, P against the prescribed d (and −`reaction_top_y`); right, the kinetic
# energy over the elastic one.


def plot_hertz(results, checks, h, path):
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    top = 0.0
    for k, res in enumerate(results):
        c, ts, zone = COLOURS[k], res["ts"], res["zone"]
        label = f"{res['pair']}, constrain {res['constrain']}"
        a_h = PUNCH.hertz_half_width(ts["contact_force"], R, E, NU)
        a = 0.5 * (zone[:, 0] + zone[:, 1])
        every = slice(1, None, 4)
        axes[0].errorbar(a_h[every], a[every], yerr=0.5 * (zone[every, 1] - zone[every, 0]), fmt="o", ms=3,
                         color=c, alpha=0.8, lw=0.8, label=f"measured, {label}")
        chk = checks[k]
        axes[0].plot(chk[:, 5], chk[:, 4], "s", mfc="none", mec=c, ms=9, label=f"checked loads, {label}")
        top = max(top, a_h.max())
        x, p = res["pressure"]
        order = np.argsort(x)
        axes[1].plot(x[order], p[order], "o-", color=c, ms=3, lw=0.8, label=label)
        P = ts["contact_force"][-1]
        a0 = PUNCH.hertz_half_width(P, R, E, NU)
        xx = np.linspace(-a0, a0, 400)
        axes[1].plot(xx, 2 * P / (np.pi * a0 ** 2) * np.sqrt(np.maximum(a0 ** 2 - xx ** 2, 0.0)), "--", color=c,
                     lw=1.2, label=f"Hertz, P = {P:.1f} N/mm (a = {a0:.2f} mm)")
    s = np.linspace(0.0, 1.05 * top, 50)
    axes[0].plot(s, s, "k", lw=1.5, label="Hertz: a = $\\sqrt{4PR/(\\pi E^*)}$")
    axes[0].fill_between(s, s - h / 2 - REL_TOL * s, s + h / 2 + REL_TOL * s, color="0.85",
                         label=f"tolerance $\\pm$(h/2 + {REL_TOL:.0%} a), h = {h:g} mm")
    axes[0].set_xlabel("Hertz's half-width $\\sqrt{4PR/(\\pi E^*)}$ (mm), P = contact force")
    axes[0].set_ylabel("measured contact half-width a (mm)")
    axes[0].set_xlim(0.0, 1.05 * top)
    axes[0].set_ylim(0.0, 1.1 * top)
    axes[0].set_title("contact half-width over the loading")
    axes[1].set_xlim(-1.3 * top, 1.3 * top)
    axes[1].set_xlabel("x (mm)")
    axes[1].set_ylabel("contact pressure (N/mm$^2$)")
    axes[1].set_title("contact pressure at the final load")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(f"Elastic disc (R = {R:g} mm, E = {E:g} N/mm$^2$, $\\nu$ = {NU:g}) pressed on a rigid flat by "
                 f"its top arc, plane strain, midpoint scheme")
    fig.tight_layout()
    return save(fig, path)


def plot_force(results, path):
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for k, res in enumerate(results):
        c, ts = COLOURS[k], res["ts"]
        label = f"{res['pair']}, constrain {res['constrain']}"
        d = push_at_force_time(ts["t"])
        axes[0].plot(d, ts["contact_force"], "-", color=c, lw=1.5, label=f"contact force P, {label}")
        axes[0].plot(d, -ts["reaction_top_y"], ":", color="k" if k == 0 else c, lw=1.2,
                     label=f"punch's reaction $-$reaction_top_y, {label}")
        ratio = ts["kinetic"][1:] / ts["elastic"][1:]
        axes[1].semilogy(1e3 * ts["t"][1:], ratio, color=c, label=label)
    axes[0].set_xlabel("prescribed displacement d of the top arc (mm)")
    axes[0].set_ylabel("force per mm of thickness (N/mm)")
    axes[0].set_title("force against indentation (no closed form in 2-D: measured)")
    axes[1].set_xlabel("t (ms)")
    axes[1].set_ylabel("kinetic energy / elastic energy")
    axes[1].set_title(f"how quasi-static: ramp {1e3 * RAMP:g} ms")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    return save(fig, path)


# ## Running the demo

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="An elastic disc pressed on a rigid flat by a prescribed "
                                                 "displacement, against Hertz's line contact")
    parser.add_argument("--h", type=float, default=0.125, help="mesh size near the contact (mm, default 0.125)")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "output" / "punch")
    args = parser.parse_args()
    if COMM.rank == 0:
        args.out.mkdir(parents=True, exist_ok=True)
    dt = 2e-3 if os.environ.get("CI") else 1e-3
    results = [run(pair, constrain, args.h, dt, args.out / f"punch_{pair.replace('/', '-')}")
               for pair, constrain in RUNS]
    checks = [compare(res, args.h) for res in results] if COMM.rank == 0 else None
    if COMM.rank == 0:
        for res, chk in zip(results, checks):
            say(f"{res['pair']}, constrain {res['constrain']}:")
            say("     d (mm)   P (N/mm)   a_in    a_out   a (mm)  Hertz a   a/Hertz-1   kinetic/elastic  |P+R_y|/P")
            for d, P, a_in, a_out, a, a_h, ke, rel, _ in chk:
                say(f"    {d:7.4f}  {P:8.3f}   {a_in:6.3f}  {a_out:6.3f}  {a:6.3f}  {a_h:6.3f}    {a / a_h - 1:+7.2%}"
                    f"      {ke:9.2e}       {rel:8.2e}")
        say("wrote", args.out / plot_hertz(results, checks, args.h, args.out / "punch_hertz.png"))
        say("wrote", args.out / plot_force(results, args.out / "punch_force.png"))
    checks = COMM.bcast(checks, root=0)

    # ## What the runs show
    #
    # At every checked load (a from 0.7 to 2.3 mm, 6 to 18 cells, a/R up to 0.12) the measured
    # half-width is within h/2 + 5 % of Hertz's (measured with h = 0.125 mm: at most 0.032 mm off,
    # 4.4 % at the smallest load and under 1 % above 150 N/mm, P1+/P0; 0.029 mm, 2.1 %, P2/P1),
    # the kinetic energy is below 1 % of the elastic one (measured 0.4 % at the smallest checked
    # load, 4e-6 at the end of the ramp) and the contact force equals the punch's reaction within
    # 1 % (measured 0.23 %).
    worst = 0.0
    for res, chk in zip(results, checks):
        where = f"{res['pair']}, constrain {res['constrain']}"
        for d, P, a_in, a_out, a, a_h, ke, rel, n in chk:
            assert a_h >= 4 * args.h and a_h <= 0.15 * R, f"{where}: load P = {P:.2f} outside Hertz's check range"
            assert abs(a - a_h) <= 0.5 * args.h + REL_TOL * a_h, \
                f"{where}: at d = {d:.4f} mm, P = {P:.2f} N/mm the contact half-width {a:.3f} mm is off Hertz's " \
                f"{a_h:.3f} mm by more than h/2 + {REL_TOL:.0%}"
            assert ke < 0.01, f"{where}: at d = {d:.4f} mm the kinetic energy is {ke:.2%} of the elastic one"
            assert rel < 0.01, f"{where}: at d = {d:.4f} mm contact force and reaction differ by {rel:.2%}"
            worst = max(worst, abs(a - a_h) / a_h)
    say(f"checked: the contact half-width within h/2 + {REL_TOL:.0%} of Hertz's at {len(FRACTIONS)} loads of each run "
        f"(largest relative difference {worst:.1%}); kinetic < 1 % of elastic energy; P = -reaction_top_y within 1 %")
