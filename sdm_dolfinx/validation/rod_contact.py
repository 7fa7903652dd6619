"""The 1-D rod's contact point under the midpoint scheme: why U^{n+1}(0) alternates and the energy swings
during the sustained contact, measured (the rod: :mod:`sdm_dolfinx.problems.rod1d`, GetFEM's
demo_dynamic_contact_1D.py).

What the runs show (``python -m sdm_dolfinx rod1d --T 3``, NX = 20, P2/P1, dt = 2e-3): in the contact
phase t in [1, 2) u(0) = U^{n+1}(0) is +3.1e-3, -3.1e-3, +3.1e-3, ... every step (not smaller at
dt = 1e-3 or 5e-4; +-7.2e-3 with P1+/P0), and the energy column swings between 0.1219 and 0.1280
(exact: 1/8) while the contact set does not change. None of the three suspects is wrong: the mass is
the paper's M = B^T C^-1 B, the constrained iterate is the paper's U^{n+1/2} (scheme (14)) and the
velocity update is (14)'s. The cause, derived from the paper and checked by the runs below:

1. *Massless modes are infinitely stiff* (paper, section 2). M is singular; its kernel F = Ker B
   (the dimension count of condition (7)) holds displacements without inertia, and condition (7)
   says some of them move the contact node (in 1-D the contact dof itself has a mass: M_00 = h/18
   for P2/P1 with the lumped C, h/36 for P1+/P0, whose vertex basis function in 1-D is P2's; what is
   massless is a mode through it). The
   semi-discrete solution (Theorem 1) keeps the F-part of U at the static value U_F(U_{F^c}), so at
   t = 0+ it is U(0+) = Pi U_0 = argmin {J(U): B U = B U_0, U in K^h}: the F-part of U_0 jumps.
2. *The midpoint scheme does not damp them* (derived). (14) computes U^{n+1/2} with its F-part
   static (M kills the inertia terms on F), then U^{n+1} = 2 U^{n+1/2} - U^n extrapolates: an
   F-error e of U^n comes back as -e in U^{n+1} (the midpoint rule's stability function
   (1 + z/2)/(1 - z/2) at z = infinity is -1; backward Euler's 1/(1 - z) is 0 and removes it in one
   step: measured, its u(0) never alternates). So U^n = (the semi-discrete solution) + (-1)^n e,
   e changing only by O(dt^2) in a smooth phase and by O(v dt) at an impact or a release.
3. *The rod's U_0 is not static on F* (derived, then measured). u0 = 1/2 - x/2 carries the strain
   -1/2 at the traction-free end x = 0 (the exact solution releases it by a wave). The difference
   e = U_0 - Pi U_0 minimises 1/2 a(w, w) + w(0)/2 over F: for P1+/P0 (in 1-D the pair P2/P0) the
   vertex values of the minimiser obey w_{i+1} + 4 w_i + w_{i-1} = 0, so w_i = w_0 (sqrt 3 - 2)^i and
   e(0) = h / (4 sqrt 3) (7.22e-3 at h = 1/20); for P2/P1, e(0) = h / (4 sqrt 15) (3.23e-3 at
   h = 1/20; measured to 10 digits at NX = 20, 40, 80, no derivation here). Neither depends on dt,
   nor on how C is treated (F = Ker B). The mode holds the energy delta = 1/2 e^T A e = e(0)/4 of
   the reported 1/8 (1.80e-3 and 8.07e-4 at h = 1/20).
4. *In the sustained contact* U^{n+1/2}(0) = 0 exactly, so U^{n+1}(0) = -U^n(0): u(0) is +-d for the
   whole phase, d = |U^n(0)| at the step the contact starts, e(0) to within v dt (v = 1/2 the
   impact speed). The energy J^h(U^n, Vbar^n) that the time series reports obeys exactly (the
   discrete energy identity of (14))

       E^{n+1} - E^n = lambda^{n+1/2} (U^{n+1}(0) - U^n(0)),

   zero in flight (exact conservation, Theorem 2's J^h with Vbar^n for U'), and -+2 lambda d at every
   contact step: the swing is the work of the contact force on the alternating dip. The
   semi-discrete persistency condition (Proposition 1, lambda du(0)/dt = 0) has no counterpart at the
   integer steps.

Started from Pi U_0 instead of the interpolant (:func:`relaxed_problem`, this study's second start),
the alternation in flight is below 3e-5, the dip in contact is the impact's kick only (below v dt / 2:
1.0e-4 and 9.5e-5 for P2/P1 at dt = 2e-3 and 1e-3, 2.5e-5 at 5e-4), and the energy stays within 2e-4 of
its initial value through the contact (1.2e-6 after the release); but that value is 1/8 - delta,
the energy the semi-discrete problem keeps after its instantaneous relaxation at t = 0+. The package,
like the paper's scheme and GetFEM, starts from the interpolant.

``python -m sdm_dolfinx.validation.rod_contact --out DIR`` writes ``rod_contact.json``,
``rod_contact.md`` (the table) and ``rod_contact.png`` (u(0) and the energy through the contact, even
and odd steps apart); the report (``make figures``) has it as a section.
"""
import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.problems import rod1d
from sdm_dolfinx.run import simulate

#: the pairs of the study (the singular dynamic method's two pairs on the rod)
PAIRS = ("P2/P1", "P1+/P0")
#: cells of the rod (GetFEM's demo) and the time steps: the rod's default and its half
NX = 20
DTS = (2e-3, 1e-3)
#: the end of the runs: the first flight, the contact phase [1, 2) and the start of the second flight
T_END = 2.1
#: the two initial states: the interpolant of u0 (what every run does) and Pi U_0 (the semi-discrete solution's
#: state at t = 0+, item 1 of the docstring)
STARTS = ("interpolant", "relaxed")
#: the impact speed |u_t(0)| of the rod
V_IMPACT = 0.5
#: windows of the first flight and of the sustained contact (clear of the impact and the release)
FLIGHT = (0.1, 0.9)
CONTACT = (1.1, 1.9)


class RodContactError(SdmError, ValueError):
    """A pair this study has no projection for."""


def mode_amplitude(pair, h):
    """e(0) = (U_0 - Pi U_0)(0), the alternating mode's amplitude at the contact point: h / (4 sqrt 3) for
    P1+/P0 (derived: docstring, item 3), h / (4 sqrt 15) for P2/P1 (measured to 10 digits)."""
    if pair == "P1+/P0":
        return h / (4.0 * math.sqrt(3.0))
    if pair == "P2/P1":
        return h / (4.0 * math.sqrt(15.0))
    raise RodContactError(f"rod_contact: no amplitude for pair {pair!r}; choose one of {', '.join(PAIRS)}")


# ---------------------------------------------------------------- Pi U_0, assembled here (independently)
#: P2 on a cell of length h, basis (left vertex, right vertex, mid-edge): h * stiffness = _K2, B rows
#: int psi phi / h for H = P0 (one row) and H = P1 (the two hats)
_K2 = np.array([[7.0, 1.0, -8.0], [1.0, 7.0, -8.0], [-8.0, -8.0, 16.0]]) / 3.0
_B_P0 = np.array([[1 / 6, 1 / 6, 2 / 3]])
_B_P1 = np.array([[1 / 6, 0.0, 1 / 3], [0.0, 1 / 6, 1 / 3]])


def _p2_dofs(nx):
    """Global P2 dofs of each cell: vertices 0..nx, then mid-edges nx+1..2nx."""
    return [(k, k + 1, nx + 1 + k) for k in range(nx)]


def relaxed_start(pair, nx=NX):
    """Pi U_0 of the rod (P2 nodal values: vertices 0..nx at x = i h, then the mid-edges): the minimiser of
    J(U) = 1/2 a(U, U) over B U = B U_0 and U(1) = 0 (no load; the constraint u(0) >= 0 is inactive at
    t = 0), assembled here in numpy (W^h = P2, which P1+ spans in 1-D; H^h = P0 or P1, exact integrals),
    independently of the package's matrices. Returns (Pi U_0, U_0, e(0), delta = J(U_0) - J(Pi U_0))."""
    if pair not in PAIRS:
        raise RodContactError(f"rod_contact: no projection for pair {pair!r}; choose one of {', '.join(PAIRS)}")
    h = 1.0 / nx
    n = 2 * nx + 1
    A = np.zeros((n, n))
    rows = _B_P0 if pair == "P1+/P0" else _B_P1
    nh = nx if pair == "P1+/P0" else nx + 1
    B = np.zeros((nh, n))
    for k, dofs in enumerate(_p2_dofs(nx)):
        A[np.ix_(dofs, dofs)] += _K2 / h
        hdofs = [k] if pair == "P1+/P0" else [k, k + 1]
        B[np.ix_(hdofs, dofs)] += h * rows
    x = np.r_[np.arange(nx + 1) * h, (np.arange(nx) + 0.5) * h]
    U0 = 0.5 - 0.5 * x
    free = np.setdiff1d(np.arange(n), [nx])                 # u(1) = 0: vertex nx
    Af, Bf = A[np.ix_(free, free)], B[:, free]
    # KKT of min 1/2 U^T A U subject to B U = B U_0 (B has full row rank on the free dofs)
    kkt = np.block([[Af, Bf.T], [Bf, np.zeros((nh, nh))]])
    sol = np.linalg.solve(kkt, np.r_[np.zeros(len(free)), Bf @ U0[free]])
    U = np.zeros(n)
    U[free] = sol[:len(free)]
    e = U0 - U
    delta = 0.5 * U0 @ A @ U0 - 0.5 * U @ A @ U
    return U, U0, float(e[0]), float(delta)


def p2_function(values, nx=NX):
    """The piecewise quadratic with the P2 nodal ``values`` of :func:`relaxed_start`, as a callable
    ``x (3, m) -> (m,)`` for ``Function.interpolate`` (exact for W^h = P2 and P1+, which span P2)."""
    h = 1.0 / nx
    values = np.asarray(values, dtype=float)

    def u(x):
        k = np.clip(np.floor(x[0] / h).astype(int), 0, nx - 1)
        s = x[0] / h - k
        a, b, m = values[k], values[k + 1], values[nx + 1 + k]
        return a * (1 - s) * (1 - 2 * s) + b * s * (2 * s - 1) + m * 4 * s * (1 - s)
    return u


def relaxed_problem(pair, nx=NX, comm=MPI.COMM_WORLD):
    """The rod started from Pi U_0 (the semi-discrete solution's state at t = 0+) instead of the interpolant
    of u0: the rod Problem with only ``u0`` replaced (its name says so; it is not rebuildable from
    parameters)."""
    U, _, _, _ = relaxed_start(pair, nx)
    p = rod1d.problem(comm, NX=nx)
    return dataclasses.replace(p, name="rod1d_relaxed", u0=p2_function(U, nx), args={})


# ------------------------------------------------------------------------------------------ the runs
def _window(t, span):
    return (t > span[0]) & (t < span[1])


def measure(t, u, E, lam):
    """The study's numbers from a run's time series (t, u(0) = U^n(0), the energy E^n, the multiplier
    lambda of the step that ends at row n):

    * ``flight_alternation``: max |u_{n+1} - 2 u_n + u_{n-1}| / 4 in the first flight (the (-1)^n
      mode's amplitude; a smooth motion contributes dt^2 u'' / 4);
    * ``dip_min``, ``dip_max``: min and max of |u(0)| in the sustained contact;
    * ``antisymmetry``: max |u_{n+1} + u_n| over contact steps (U^{n+1/2}(0) = 0 makes it 0);
    * ``energy_contact``: (min, max) of E in the sustained contact; ``energy_flight_drift``: max |E - E_0|
      over the first flight;
    * ``identity``: max over every step of |E^{n+1} - E^n - lambda^{n+1/2} (u_{n+1} - u_n)|."""
    f, c = _window(t, FLIGHT), _window(t, CONTACT)
    uf = u[f]
    alt = float(np.max(np.abs(uf[2:] - 2 * uf[1:-1] + uf[:-2])) / 4.0)
    cidx = np.flatnonzero(c)
    anti = float(np.max(np.abs(u[cidx[1:]] + u[cidx[:-1]])))
    ident = float(np.max(np.abs(np.diff(E) - lam[1:] * np.diff(u))))
    return {"flight_alternation": alt, "dip_min": float(np.min(np.abs(u[c]))),
            "dip_max": float(np.max(np.abs(u[c]))), "antisymmetry": anti,
            "energy_0": float(E[0]), "energy_contact": [float(np.min(E[c])), float(np.max(E[c]))],
            "energy_flight_drift": float(np.max(np.abs(E[f] - E[0]))), "identity": ident,
            "lambda_max": float(np.max(lam[c]))}


def run_one(pair, dt, start, nx=NX, T=T_END, comm=MPI.COMM_WORLD):
    """One run of the rod (midpoint scheme, the pair's default C) from the ``start`` state; its row
    (:func:`measure`'s numbers, the series, the expected e(0) and delta) (collective)."""
    problem = relaxed_problem(pair, nx, comm) if start == "relaxed" else rod1d.problem(comm, NX=nx)
    t0 = time.perf_counter()
    r = simulate(problem, pair=pair, scheme="midpoint", dt=dt, T=T, comm=comm)
    ts = r.timeseries
    t, u, E, lam = (np.asarray(ts[k], dtype=float) for k in ("t", "u_probe", "energy", "lambda_probe"))
    _, _, e0, delta = relaxed_start(pair, nx)
    row = {"pair": pair, "dt": dt, "start": start, "NX": nx, "h": 1.0 / nx, "e0": e0,
           "e0_closed_form": mode_amplitude(pair, 1.0 / nx), "delta": delta, "seconds": time.perf_counter() - t0}
    row.update(measure(t, u, E, lam))
    row["series"] = {"t": t.tolist(), "u": u.tolist(), "energy": E.tolist(), "lambda": lam.tolist()}
    return row


def study(pairs=PAIRS, dts=DTS, starts=STARTS, nx=NX, comm=MPI.COMM_WORLD, say=None):
    """Every (pair, dt, start) run (collective); the rows in that order."""
    rows = []
    for pair in pairs:
        for start in starts:
            for dt in dts:
                row = run_one(pair, dt, start, nx, comm=comm)
                if say:
                    say(f"  rod contact: {pair}, {start}, dt = {dt:g}: |u(0)| in contact {row['dip_max']:.3e}, "
                        f"energy {row['energy_contact'][0]:.5f}-{row['energy_contact'][1]:.5f}")
                rows.append(row)
    return rows


# --------------------------------------------------------------------------------- what it concludes
def checks(rows):
    """What the explanation predicts, each checked on the rows (name -> bool):

    * ``mode_is_e0``: from the interpolant, the flight alternation is e(0) (closed form) within 1 %, at
      every dt;
    * ``dip_not_shrinking``: from the interpolant, the contact dip d is e(0) within v dt;
    * ``dip_antisymmetric``: U^{n+1}(0) = -U^n(0) in contact to 1e-9;
    * ``identity``: the energy identity holds to 1e-9 at every step;
    * ``flight_exact``: the energy is constant to 1e-9 (round-off over 900 steps) in the first flight;
    * ``relaxed_dip``: from Pi U_0 the dip is below v dt / 2 and the flight alternation below 1e-4;
    * ``relaxed_energy``: from Pi U_0 the energy starts at 1/8 - delta (to 1e-12) and stays within
      2 lambda_max v dt / 2 of it in contact."""
    interp = [r for r in rows if r["start"] == "interpolant"]
    relaxed = [r for r in rows if r["start"] == "relaxed"]
    out = {
        "mode_is_e0": all(abs(r["flight_alternation"] / r["e0_closed_form"] - 1) < 0.01 for r in interp),
        "dip_not_shrinking": all(abs(r["dip_max"] - r["e0_closed_form"]) <= V_IMPACT * r["dt"]
                                 and abs(r["dip_min"] - r["e0_closed_form"]) <= V_IMPACT * r["dt"] for r in interp),
        "dip_antisymmetric": all(r["antisymmetry"] < 1e-9 for r in interp),
        "identity": all(r["identity"] < 1e-9 for r in rows),
        "flight_exact": all(r["energy_flight_drift"] < 1e-9 for r in rows),
        "relaxed_dip": all(r["dip_max"] <= V_IMPACT * r["dt"] / 2 and r["flight_alternation"] < 1e-4
                           for r in relaxed),
        "relaxed_energy": all(abs(r["energy_0"] - (rod1d.ENERGY - r["delta"])) < 1e-12
                              and max(abs(e - r["energy_0"]) for e in r["energy_contact"])
                              <= r["lambda_max"] * V_IMPACT * r["dt"] for r in relaxed),
    }
    return out


HEADER = ("pair", "start", "dt", "e(0), closed form", "alternation in flight", "|u(0)| in contact",
          "energy in contact", "E(0)", "max |ΔE − λ Δu(0)|")


def table_rows(rows):
    """The table's rows (strings)."""
    out = []
    for r in rows:
        lo, hi = r["energy_contact"]
        dip = (f"{r['dip_max']:.3e}" if abs(r["dip_max"] - r["dip_min"]) < 5e-7 * max(r["dip_max"], 1e-300)
               else f"{r['dip_min']:.2e} to {r['dip_max']:.2e}")
        out.append((r["pair"], r["start"], f"{r['dt']:g}", f"{r['e0_closed_form']:.3e}",
                    f"{r['flight_alternation']:.2e}", dip, f"{lo:.5f} to {hi:.5f}", f"{r['energy_0']:.6f}",
                    f"{r['identity']:.1e}"))
    return out


def table(rows):
    """The table in Markdown."""
    def cells(values):
        return "| " + " | ".join(v.replace("|", "\\|") for v in values) + " |"
    lines = [cells(HEADER), "|" + "---|" * len(HEADER)] + [cells(r) for r in table_rows(rows)]
    return "\n".join(lines) + "\n"


def plot(rows, path):
    """u(0) and the energy through the contact, one column per pair: the interpolant start at each dt (even
    and odd steps drawn apart: the two branches of the alternation) and the relaxed start at the largest dt."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    pairs = list(dict.fromkeys(r["pair"] for r in rows))
    fig, axes = plt.subplots(2, len(pairs), figsize=(6.2 * len(pairs), 7.5), squeeze=False, sharex=True)
    colours = {dt: c for dt, c in zip(sorted({r["dt"] for r in rows}, reverse=True), ("C0", "C1", "C2", "C4"))}
    for j, pair in enumerate(pairs):
        au, ae = axes[0, j], axes[1, j]
        mine = [r for r in rows if r["pair"] == pair]
        dt_max = max(r["dt"] for r in mine)
        for r in mine:
            if r["start"] == "relaxed" and r["dt"] != dt_max:
                continue
            t, u, E = (np.asarray(r["series"][k]) for k in ("t", "u", "energy"))
            keep = (t > 0.8) & (t < 2.1)
            if r["start"] == "interpolant":
                col = colours[r["dt"]]
                for parity, ls in ((0, "-"), (1, "--")):
                    sel = keep & (np.arange(len(t)) % 2 == parity)
                    lab = f"dt = {r['dt']:g}, {'even' if parity == 0 else 'odd'} steps"
                    au.plot(t[sel], u[sel], ls, color=col, lw=1.0, label=lab)
                    ae.plot(t[sel], E[sel], ls, color=col, lw=1.0, label=lab)
            else:
                au.plot(t[keep], u[keep], "-", color="k", lw=1.6, label=f"from Pi U0, dt = {r['dt']:g}")
                ae.plot(t[keep], E[keep], "-", color="k", lw=1.6, label=f"from Pi U0, dt = {r['dt']:g}")
        e0 = mode_amplitude(pair, mine[0]["h"])
        for s in (1, -1):
            au.axhline(s * e0, color="0.5", lw=0.6, ls=":")
        au.axhline(0.0, color="0.3", lw=0.6)
        ae.axhline(rod1d.ENERGY, color="0.3", lw=0.6, ls=":")
        au.set_ylim(-3 * e0, 4 * e0)
        au.set_title(f"{pair}, NX = {mine[0]['NX']}: u(0) = U^n(0) (dotted: ±e(0) = ±{e0:.2e})")
        ae.set_title(f"{pair}: energy J^h(U^n, V^n) (dotted: 1/8)")
        ae.set_xlabel("t")
        au.legend(fontsize=7, loc="upper right")
        ae.legend(fontsize=7, loc="lower left")
        for ax in (au, ae):
            ax.axvspan(1.0, 2.0, color="0.93", zorder=0)
            ax.grid(alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def write_outputs(rows, out):
    """``rod_contact.json`` (the rows without their series, the checks), ``rod_contact.md`` and
    ``rod_contact.png`` in ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    bare = [{k: v for k, v in r.items() if k != "series"} for r in rows]
    atomic_write_text(out / "rod_contact.json", json_text({"rows": bare, "checks": checks(rows)}))
    atomic_write_text(out / "rod_contact.md", table(rows))
    return plot(rows, out / "rod_contact.png")


class _Parser(argparse.ArgumentParser):
    """Its errors are one line (:class:`RodContactError`), not argparse's usage and exit."""

    def error(self, message):
        raise RodContactError(f"{self.prog}: error: {message}")


def main(argv=None):
    """The command line: the study into ``--out``; a bad argument or an unwritable folder is one line on
    stderr and status 2, nothing written."""
    ap = _Parser(prog="python -m sdm_dolfinx.validation.rod_contact", description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="report/rod_contact", help="the folder of the table and the figure")
    comm = MPI.COMM_WORLD
    bad = None
    try:
        args = ap.parse_args(argv)
    except RodContactError as e:
        bad = str(e)
    if bad is None and comm.rank == 0:
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            bad = f"rod_contact: {out} is not a folder"
        else:
            try:
                probe = out / ".rod_contact_probe"
                out.mkdir(parents=True, exist_ok=True)
                probe.write_text("")
                probe.unlink()
            except OSError as e:
                bad = f"rod_contact: cannot write to {out}: {e.strerror or e}"
    bad = comm.bcast(bad, root=0)
    if bad:
        if comm.rank == 0:
            print(bad, file=sys.stderr)
        return 2
    rows = study(comm=comm, say=print if comm.rank == 0 else None)
    if comm.rank == 0:
        write_outputs(rows, args.out)
        print(table(rows), end="")
        print("checks: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in checks(rows).items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
