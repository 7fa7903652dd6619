"""The ball's oblique impact with Coulomb friction: impulses, rebound and spin against
the rigid-body estimates.

Each run is the ball (:mod:`sdm_dolfinx.problems.ball`, its defaults: R = 20 mm, E = 10 N/mm^2,
nu = 0.3, rho = 1e-9 t/mm^3) falling at v = 100 mm/s with a tangential velocity vt along x
(``vt_angle`` degrees from x) onto the plane z = 0 with Coulomb friction mu (P2/P1, midpoint,
the 3-D frictional step solver :mod:`sdm_dolfinx.solvers.friction_cone`), stepped by hand
until 1.25 Hertz contact times after the touch. Per step: the normal force N (the sum of the
normal multipliers), the tangential force vector F_T = sum lam_T, the friction work
W_T = lam_T . (U^{n+1} - U^n)_t <= 0 and the normal contact's W_N; the impulses J = dt sum F
(the midpoint scheme's momentum balance: e^T M (V^{n+1} - V^n) = dt F); after the impact the
tangential velocity v_t' = e_x^T M V / m and the spin omega_y = L_y / I, I = 2/5 m R^2, with
L_y the angular momentum of the discrete velocity field about the centre of mass,

    L_y = w^T M V,     w = e_y x (X - X_c)  (interpolated exactly in P2; X_c = e^T M X / m),

the moment of the velocity about the *material* centre of mass, as the linear (small
displacement) kinematics has it: w is M-orthogonal to the translations, so L_y / w^T M w is the
rotation rate of the rigid motion nearest to V, and since A w = 0 (an infinitesimal rotation)
L_y changes only by the contact reactions' moments sum_i w(X_i) . r_i: in flight it is
conserved. (Measured: correcting L_y by the centre's travel, - ((x_c - X_c) x P)_y, as for a
rigid body in the current configuration, adds the normal impulse's moment about a centre that
has moved by v_t t, which the linear kinematics never applies: +17 % on omega at mu = 0.05.)

Rigid-body estimates (a rigid sphere, mass m, I = 2/5 m R^2, contact point at -R e_z from the
centre, normal impulse J_n = (1 + e) m v, e = 1 for the elastic rebound: J_n = 2 m v). The
tangential impulse J_t e_x acts at the contact point, so m Delta v_t = J_t and I Delta omega =
(-R e_z) x (J_t e_x) = -R J_t e_y. The contact point slides with v_c = v_t - R omega_y.

* Gross slip throughout: J_t = -mu J_n, hence Delta v_t = -mu J_n / m and omega_y =
  5 mu J_n / (2 m R); v_c = v_t - 7/2 mu J_n / m must stay >= 0, i.e.
  mu <= mu* = 2 v_t / (7 (1 + e) v) (= v_t / (7 v) for e = 1).
* mu > mu*: the contact point stops sliding (rolls/sticks) before the impact ends, v_c = 0:
  v_t + 7/2 J_t / m = 0, so J_t = -2/7 m v_t, v_t' = 5/7 v_t, omega_y = 5 v_t / (7 R), whatever mu.

An elastic sphere is tangentially compliant (Maw, Barber, Fawcett 1976, "The oblique impact of
elastic spheres", Wear 38): in the stick regime its contact zone stores tangential strain
energy and the tangential force reverses during the impact, so v_t' and omega differ from the
rigid 5/7 estimate (the tangential velocity may even reverse for a large mu); in gross slip the
compliance does not matter and the rigid estimate is the expected limit.

    python -m sdm_dolfinx.validation.ball_oblique --out report/ball_oblique
    python -m sdm_dolfinx.validation.ball_oblique --level 2 --mu 0.05 0.3 --out report/ball_oblique2

writes ``ball_oblique.json``, ``ball_oblique.md`` (the table) and ``ball_oblique.png`` (v_t' / v_t
and R omega / v_t against mu, with both rigid estimates; ``--replot JSON`` redraws).

Measured (v = v_t = 100 mm/s, so mu* = 1/7; dt = 4e-5 s, 125 steps; levels 1 and 2, 8-11 s and
28-50 s a run on one core; ``--level 1 2``):

* every run: |J_t| <= mu J_n, per step and cumulatively (to 1e-11 of J_n); friction work <= 0
  at every step; E^{n+1} - E^n = W_N + W_T to 8e-13 E^0, so E + dissipated - E^0 = sum W_N
  (2e-4 to 4e-4 E^0: the normal contact's work at landings); 2.3-3.7 Newton iterations per
  contact step on average, at most 6.
* gross slip (mu = 0.02, 0.05, 0.1 < mu*): |J_t| / J_n = mu (0.0998-0.1000) and v_t'/v_t within
  2e-4 of 1 - 2 mu v/v_t at both levels; R omega/v_t from L_y / (2/5 m R^2) is 7 / 4 / 3 %
  (level 1) and 1.1 / 1.8 / 2.0 % (level 2) below 5 mu v/v_t: L_y is 0.93-0.99 of R |J_t| (the
  contact sits at R - delta, and the normal pressure's centre is a little off the material
  axis). The rigid motion nearest to V turns faster (R omega/v_t 0.1051 / 0.2706 / 0.5462 at
  level 1, 0.1068 / 0.2651 / 0.5288 at level 2) because the pair's mass matrix (P2/P1, lumped
  C) carries only 0.886 (level 1) and 0.926 (level 2) of the sphere's rotational inertia
  w^T M w against int rho |w|^2 = 2/5 m R^2 (to 4e-4 on the curved mesh).
* stick/roll (mu = 0.2 ... 1 > mu*): not the rigid 5/7. At mu = 0.2-0.5 the elastic ball takes
  more tangential impulse than the rigid sphere's 2/7 m v_t (|J_t| / J_n 0.16-0.20 against
  0.143): v_t'/v_t 0.59-0.67, R omega/v_t 0.78-0.99; at mu = 1 less (0.115 level 1, 0.141
  level 2): v_t'/v_t 0.77 / 0.72, R omega/v_t 0.53 / 0.67. The contact's tangential compliance
  (Maw, Barber, Fawcett) stores tangential strain energy while the centre of the contact
  sticks and gives it back as the tangential force reverses; these numbers still move
  between levels 1 and 2 by up to 0.13 in R omega/v_t (mu = 1): mesh convergence of the stick
  regime needs level 3.
* the rebound v_z'/v is 1.000-1.015 (growing with mu), above the frictionless 0.9999: the
  vertical translation gains up to 3 % of its energy from the tangential motion (sum W_N stays
  2e-4 to 4e-4 E^0, so not from the normal contact's work); presumably the elastic coupling of
  the tangential traction to normal displacement (nu = 0.3), not examined further.
"""
import argparse
import math
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx import compat
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.contact.friction import make
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.study.plotting import COLOURS, pyplot, save
from sdm_dolfinx.problems import ball

#: the default study: v = 100 mm/s, vt = 100 mm/s (mu* = 1/7), level 1, dt = 4e-5 s
DEFAULT_MU = (0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0)
T_FACTOR = 1.25


def rigid_estimates(v, vt, mu, R, e=1.0):
    """The rigid sphere's outcome (derived in the module doc): ``regime`` ("slip" if mu <= mu*,
    else "roll"), ``mu_star``, ``J_t_over_m`` (mm/s), ``vt_after`` (mm/s), ``omega`` (1/s), and
    both regimes' values (``*_slip``, ``*_roll``)."""
    jn = (1.0 + e) * v                                     # J_n / m
    mu_star = 2.0 * vt / (7.0 * jn)
    slip = {"J_t_over_m": -mu * jn, "vt_after": vt - mu * jn, "omega": 5.0 * mu * jn / (2.0 * R)}
    roll = {"J_t_over_m": -2.0 / 7.0 * vt, "vt_after": 5.0 / 7.0 * vt, "omega": 5.0 * vt / (7.0 * R)}
    regime = "slip" if mu <= mu_star else "roll"
    out = {"regime": regime, "mu_star": mu_star, **(slip if regime == "slip" else roll)}
    out.update({f"{k}_slip": x for k, x in slip.items()})
    out.update({f"{k}_roll": x for k, x in roll.items()})
    return out


class Spin:
    """Angular momentum about y of the discrete velocity: L_y = w^T M V with w = e_y x (X - X_c),
    X_c the centre of mass of the reference configuration (e^T M X / m per component)."""

    def __init__(self, integ, mass):
        d = integ.discretisation
        self.integ = integ
        x = d.W.tabulate_dof_coordinates()
        bs, n = d.W.dofmap.index_map_bs, d.W.dofmap.index_map.size_local
        X = d.A.createVecLeft()
        X.array[:] = x[:n, :bs].reshape(-1)
        self.centre = np.array([integ.momentum(X, k) / mass for k in range(3)])     # e_k^T M X / m
        r = x[:n] - self.centre
        w = np.zeros((n, bs))
        w[:, 0], w[:, 2] = r[:, 2], -r[:, 0]               # e_y x r = (r_z, 0, -r_x)
        self.w = d.A.createVecLeft()
        self.w.array[:] = w.reshape(-1)
        self.Mw = d.A.createVecLeft()
        integ.mass_mult(self.w, self.Mw)
        self.inertia = self.w.dot(self.Mw)                  # the discrete I_yy = w^T M w

    def __call__(self, V):
        """L_y = w^T M V."""
        return self.Mw.dot(V)

    def fitted_rate(self, V):
        """The rotation rate of the L2-nearest rigid motion to the velocity field (P2 function
        Vbar, consistent mass: int rho w . v / int rho |w|^2), independent of the pair's M."""
        d = self.integ.discretisation
        w, v = fem.Function(d.W), fem.Function(d.W)
        for f, vec in ((w, self.w), (v, V)):
            f.x.array[:len(vec.array)] = vec.array
            f.x.scatter_forward()
        rho = d.problem.rho
        num, den = (d.comm.allreduce(fem.assemble_scalar(compat.form(rho * ufl.inner(w, g) * ufl.dx)), op=MPI.SUM)
                    for g in (v, w))
        return num / den


def run_one(level=1, dt=4e-5, mu=0.3, vt=100.0, vt_angle=0.0, v=100.0, T=None, pair="P2/P1",
            comm=MPI.COMM_WORLD, **problem_args):
    """One oblique impact stepped by hand; returns its row (every rank; numbers reduced)."""
    t0 = time.perf_counter()
    problem = ball.problem(comm, level=level, v=v, vt=vt, vt_angle=vt_angle, **problem_args)
    prm, ref = problem.parameters, ball.hertz_of(problem)
    T = prm["height"] / v + T_FACTOR * ref["t_c"] if T is None else T
    d = Discretisation(problem, pair)
    integ = Integrator(d, "midpoint", dt, friction=make("coulomb", mu=mu) if mu > 0 else None)
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    mass = ball.total_mass(problem)
    spin = Spin(integ, mass)
    n_steps = int(round(T / dt))
    hist = {k: np.zeros(n_steps) for k in ("N", "Tx", "Ty", "W_T", "W_N", "dE", "E", "its", "n_slip")}
    E = sum(integ.energies(U, V, 0.0))
    E0 = E
    for k in range(n_steps):
        Un = U.array.copy()
        info = integ.step(U, V, k, k * dt)
        du = U.array - Un
        lam = integ.lam
        ft = info.get("tangential_force_t", [0.0, 0.0])
        W_N = comm.allreduce(float(lam @ du[d.cdofs]), op=MPI.SUM)
        E_new = sum(integ.energies(U, V, (k + 1) * dt))
        hist["N"][k] = comm.allreduce(float(np.sum(lam)), op=MPI.SUM)
        hist["Tx"][k], hist["Ty"][k] = ft
        hist["W_T"][k], hist["W_N"][k] = info.get("friction_work", 0.0), W_N
        hist["dE"][k], hist["E"][k], E = E_new - E, E_new, E_new
        hist["its"][k], hist["n_slip"][k] = info.get("its", 0), info.get("n_slip", 0)
    L, omega_fit = spin(V), spin.fitted_rate(V)
    vt_after = [integ.momentum(V, 0) / mass, integ.momentum(V, 1) / mass]
    vz_after = integ.momentum(V, 2) / mass
    integ.destroy()
    R = prm["radius"]
    I_rigid = 0.4 * mass * R ** 2
    Jn = dt * hist["N"].sum()
    Jt = dt * np.array([hist["Tx"].sum(), hist["Ty"].sum()])
    contact = hist["N"] > 0
    cum_n, cum_t = np.cumsum(dt * hist["N"]), np.cumsum(dt * np.hypot(hist["Tx"], hist["Ty"]))
    est = rigid_estimates(v, vt, mu, R)
    return {"level": level, "dt": dt, "mu": mu, "vt": vt, "vt_angle": vt_angle, "v": v, "mass": mass,
            "radius": R, "steps": n_steps, "J_n": Jn, "J_t": Jt.tolist(), "J_t_norm": float(np.hypot(*Jt)),
            "ratio_total": float(np.hypot(*Jt) / Jn) if Jn > 0 else 0.0,
            "ratio_step_max": float(np.max(np.hypot(hist["Tx"], hist["Ty"])[contact] / hist["N"][contact],
                                           initial=0.0)),
            "ratio_cumulative_max": float(np.max((cum_t - mu * cum_n) / max(Jn, 1e-300))),
            "J_n_over_2mv": Jn / (2.0 * mass * v), "vt_after": vt_after, "vz_after": vz_after,
            "rebound": vz_after / v, "L_y": L, "L_y_over_R_J_t": L / (-R * Jt[0]) if Jt[0] else None,
            "omega_y": L / I_rigid, "omega_y_fit": omega_fit, "I_discrete_over_rigid":
            spin.inertia / I_rigid, "omega_y_discrete_I": L / spin.inertia,
            "energy_0": E0, "energy_end": float(hist["E"][-1]), "dissipated": float(-hist["W_T"].sum()),
            "W_T_max": float(hist["W_T"].max()), "W_N_total": float(hist["W_N"].sum()),
            "balance_max": float(np.max(np.abs(hist["dE"] - hist["W_N"] - hist["W_T"])) / E0),
            "its_max": int(hist["its"].max()), "its_mean_contact": float(hist["its"][contact].mean())
            if contact.any() else 0.0, "rigid": est, "seconds": time.perf_counter() - t0,
            "history": {k: a.tolist() for k, a in hist.items()}}


def table(rows):
    """The study's Markdown table."""
    head = ("| level | mu | vt (mm/s) | regime (mu* ) | J_n/(2mv) | |J_t|/J_n | max step |F_T|/N | "
            "vt'/vt | rigid vt'/vt | R omega/vt (L/I; fit) | rigid R omega/vt | rebound | dissipated/E0 | Newton "
            "its (mean, max) | wall (s) |\n|" + "---|" * 16 + "\n")
    lines = []
    for r in rows:
        e, vt = r["rigid"], r["vt"]
        lines.append(f"| {r['level']} | {r['mu']:g} | {vt:g} | {e['regime']} ({e['mu_star']:.3f}) | "
                     f"{r['J_n_over_2mv']:.4f} | {r['ratio_total']:.4f} | {r['ratio_step_max']:.4f} | "
                     f"{r['vt_after'][0] / vt:.4f} | {e['vt_after'] / vt:.4f} | "
                     f"{r['omega_y'] * r['radius'] / vt:.4f}; {r['omega_y_fit'] * r['radius'] / vt:.4f} | "
                     f"{e['omega'] * r['radius'] / vt:.4f} | "
                     f"{r['rebound']:.4f} | {r['dissipated'] / r['energy_0']:.2e} | "
                     f"{r['its_mean_contact']:.1f}, {r['its_max']} | {r['seconds']:.0f} |")
    return head + "\n".join(lines) + "\n"


def plot(rows, path):
    """v_t'/v_t and R omega/v_t against mu, with the rigid estimates (slip and roll)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(12, 5.0))
    vt, v = rows[0]["vt"], rows[0]["v"]
    lo, hi = min(r["mu"] for r in rows) / 1.5, max(r["mu"] for r in rows) * 1.5
    mus = np.geomspace(lo, hi, 400)
    est = [rigid_estimates(v, vt, m, rows[0]["radius"]) for m in mus]
    R = rows[0]["radius"]
    ax.plot(mus, [e["vt_after"] / vt for e in est], "-", color=COLOURS[0], lw=1.5,
            label="rigid sphere: v_t'/v_t (slip: 1 - 2 mu v/v_t; roll: 5/7)")
    ax.plot(mus, [e["omega"] * R / vt for e in est], "-", color=COLOURS[1], lw=1.5,
            label="rigid sphere: R omega/v_t (slip: 5 mu v/v_t; roll: 5/7)")
    for level, marker in ((1, "o"), (2, "s"), (3, "^")):
        sel = [r for r in rows if r["level"] == level]
        if not sel:
            continue
        mu = [r["mu"] for r in sel]
        fill = {} if level == 1 else {"mfc": "none"}
        ax.plot(mu, [r["vt_after"][0] / vt for r in sel], marker, color=COLOURS[0], ms=7, **fill,
                label=f"elastic ball, level {level}: v_t'/v_t")
        ax.plot(mu, [r["omega_y"] * R / vt for r in sel], marker, color=COLOURS[1], ms=7, **fill,
                label=f"level {level}: R omega_y/v_t, omega_y = L_y / (2/5 m R²)")
        ax.plot(mu, [r["omega_y_fit"] * R / vt for r in sel], "x" if level == 1 else "+", color=COLOURS[3], ms=8,
                label=f"level {level}: R omega/v_t of the rigid motion nearest to V")
    mu_star = rows[0]["rigid"]["mu_star"]
    ax.axvline(mu_star, color="0.4", ls="--", lw=1.0)
    ax.text(mu_star, 0.02, f" mu* = {mu_star:.3f}\n (slip | roll)", fontsize=9, color="0.3", va="bottom")
    ax.set_xscale("log")
    ax.set_xlim(lo, hi)
    ax.set_xlabel("Coulomb coefficient mu")
    ax.set_ylabel("after the impact, relative to v_t")
    ax.set_ylim(-0.05, 1.15)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7.5, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title(f"oblique impact: v = {v:g} mm/s, v_t = {vt:g} mm/s, R = {R:g} mm (rigid estimates: lines)")
    fig.tight_layout()
    return save(fig, path)


def write_outputs(rows, out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "ball_oblique.json", json_text(rows))
    atomic_write_text(out / "ball_oblique.md", table(rows))
    plot(rows, out / "ball_oblique.png")


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m sdm_dolfinx.validation.ball_oblique", description=__doc__.splitlines()[0])
    ap.add_argument("--level", type=int, nargs="+", default=[1])
    ap.add_argument("--dt", type=float, default=4e-5)
    ap.add_argument("--mu", type=float, nargs="+", default=list(DEFAULT_MU))
    ap.add_argument("--vt", type=float, default=100.0, help="tangential speed (mm/s)")
    ap.add_argument("--v", type=float, default=100.0, help="normal speed (mm/s)")
    ap.add_argument("--out", default="report/ball_oblique")
    ap.add_argument("--replot", default=None, metavar="JSON", help="redraw from a ball_oblique.json instead of running")
    args = ap.parse_args(argv)
    if args.replot:
        import json
        rows = json.loads(Path(args.replot).read_text())
        if MPI.COMM_WORLD.rank == 0:
            write_outputs(rows, args.out)
            print(table(rows), end="")
        return 0
    if not all(m > 0 and math.isfinite(m) for m in args.mu) or args.vt < 0 or args.v <= 0:
        print("ball_oblique: mu must be > 0, vt >= 0, v > 0", file=sys.stderr)
        return 2
    comm, rows = MPI.COMM_WORLD, []
    for level in args.level:
        for mu in args.mu:
            row = run_one(level, args.dt, mu, args.vt, v=args.v, comm=comm)
            rows.append(row)
            if comm.rank == 0:
                print(f"level {level} mu {mu:g}: |J_t|/J_n {row['ratio_total']:.4f}, vt'/vt "
                      f"{row['vt_after'][0] / args.vt:.4f}, R omega/vt {row['omega_y'] * row['radius'] / args.vt:.4f}"
                      f" ({row['rigid']['regime']}), {row['seconds']:.0f} s", flush=True)
    if comm.rank == 0:
        write_outputs(rows, args.out)
        print(table(rows), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
