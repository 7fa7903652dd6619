"""The report's section "Finite strain" (not in the paper): the runs of
:mod:`sdm_dolfinx.validation.finite_strain` (the spinning square, the rolling disc, the ball as its speed
grows) and :mod:`sdm_dolfinx.validation.finite_strain_patch` (the patch test and the small-strain limit
against closed forms), resumable, each with its figure or table and a verdict on the issue's checks. The
pushed block's closed forms in contact are the test suite's (tests/physics/test_finite_strain.py;
docs/finite_strain.md has their numbers).

The rows are kept in ``runs_dir/finite_strain/finite_strain.json`` with what defines them (the study, the
package's version); a rerun with the same definition reads them.
"""
import html
import json
import time
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx import compat
from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.study.entry import Entry, Verdict
from sdm_dolfinx.study.text import html_table
from sdm_dolfinx.validation import finite_strain as fs
from sdm_dolfinx.validation import finite_strain_patch as patch
from sdm_dolfinx.validation import finite_strain_plots as plots

ROWS_FILE = "finite_strain.json"
#: the study, quick and full: the spin's revolutions, the rolling disc's time steps, the ball's level and speeds
STUDY = {True: {"revolutions": 1.0, "rolling_dt": (2e-4,), "ball_level": 1, "speeds": (100.0, 3000.0)},
         False: {"revolutions": 3.0, "rolling_dt": (2e-4, 1e-4, 5e-5), "ball_level": 2,
                 "speeds": (100.0, 1000.0, 3000.0, 6000.0)}}
MATERIALS = ("neo-hookean", "linear")
#: the study's parts (in the stored rows' key: rows stored without one of them are recomputed)
PARTS = ("spin", "patch", "rolling", "ball")
#: the checks' tolerances: the spin's drifts and the rolling disc's step balance (the Newton tolerance's
#: scale, 1e3 x its 1e-10), the advance per revolution, the low-speed ball's t_c and F_max against Hertz
SPIN_TOL, ROLL_TOL, HERTZ_TOL = 1e-7, 0.01, 0.05
HEAD = ("<h2>Finite strain (not in the paper)</h2><p>Hyperelastic materials with the singular mass "
        "(<code>--material neo-hookean</code>, <code>svk</code> or a problem's own ψ; docs/finite_strain.md): the "
        "energy–momentum midpoint scheme (Simo–Tarnow's stress, Gonzalez's discrete gradient), each step a Newton "
        "method on the nonlinear variational inequality. Each figure sets a neo-Hookean run beside the linear "
        "model's on the same case.</p>")


def key(quick):
    """What defines the stored rows."""
    return {"study": {k: list(v) if isinstance(v, tuple) else v for k, v in STUDY[bool(quick)].items()},
            "materials": list(MATERIALS), "parts": list(PARTS), "version": compat.package_version()}


def run_study(folder, quick, comm=MPI.COMM_WORLD, say=print):
    """The rows ``{"spin", "rolling", "ball"}``, read when stored with :func:`key`, computed otherwise
    (collective); (rows, computed)."""
    path = Path(folder) / ROWS_FILE
    stored = None
    if comm.rank == 0:
        try:
            data = json.loads(path.read_text())
            stored = data["rows"] if data.get("key") == json.loads(json_text(key(quick))) else None
        except (OSError, ValueError, KeyError, AttributeError):
            stored = None
    stored = comm.bcast(stored, root=0)
    if stored is not None:
        return stored, False
    s = STUDY[bool(quick)]
    say(f"finite strain: the spin, the rolling disc and the ball at {len(s['speeds'])} speeds in {folder}")
    t0 = time.perf_counter()
    rows = {"spin": [fs.spin(m, s["revolutions"], comm) for m in MATERIALS]}
    rows["rolling"] = [fs.rolling(m, dt, comm=comm) for dt in s["rolling_dt"] for m in MATERIALS
                       if m != "linear" or dt == s["rolling_dt"][0]]
    rows["ball"] = [fs.ball(m, v, s["ball_level"], comm) for v in s["speeds"] for m in MATERIALS]
    rows["patch"] = [{**patch.patch(m, comm), **patch.small_strain(m, comm)} for m in ("svk", "neo-hookean")]
    say(f"  finite strain: {time.perf_counter() - t0:.0f} s")
    if comm.rank == 0:
        Path(folder).mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, json_text({"key": key(quick), "rows": rows}))
    comm.Barrier()
    return rows, True


def entries(study, runs_dir, out, comm=MPI.COMM_WORLD, say=print):
    """Run (unless stored) and draw the section (collective): its three entries on rank 0, [] elsewhere."""
    rows, computed = run_study(Path(runs_dir) / "finite_strain", study.quick, comm, say)
    if comm.rank != 0:
        return []
    folder = Path(out) / "finite_strain"
    folder.mkdir(parents=True, exist_ok=True)
    plots.plot_spin(rows["spin"], folder / "spin.png")
    plots.plot_rolling(rows["rolling"][:2], folder / "rolling.png")
    plots.plot_ball(rows["ball"], folder / "ball_speed.png")
    done = "Computed" if computed else "Read"
    return [spin_entry(rows["spin"], done), patch_entry(rows["patch"], done), rolling_entry(rows["rolling"], done),
            ball_entry(rows["ball"], done)]


def _by(rows, material):
    return [r for r in rows if r["material"] == material]


def spin_entry(rows, done):
    """A free body spinning: conservation (hyperelastic) against the linear model's swelling."""
    nh, lin = _by(rows, "neo-hookean")[0], _by(rows, "linear")[0]
    ok = max(nh["energy_drift"], nh["angular_drift"], nh["momentum_drift"]) <= SPIN_TOL
    text = (f"Ours (P2/P1, dt = {nh['dt']:g}, {nh['revolutions']:g} revolution(s), {nh['its']:.1f} Newton iterations "
            f"per step): the neo-Hookean square conserves its energy to {nh['energy_drift']:.1e}, its angular "
            f"momentum to {nh['angular_drift']:.1e} and its linear momenta to {nh['momentum_drift']:.0e}; after half "
            f"a turn its area is {nh['half_turn_area']:.3f} (the centrifugal stretch). The linear model's area is "
            f"{lin['half_turn_area']:.2f} there, at no elastic energy (its energy constant to "
            f"{lin['energy_drift']:.0e}). ")
    says = ("A free body (no load, no contact) spinning at ω = 2 about its centre with a small deformation rate: "
            "the continuum conserves the energy, the linear momentum and the angular momentum; the energy–momentum "
            "scheme conserves all three exactly at each step's solution, so to the tolerance of its Newton "
            f"iterations (the check: {SPIN_TOL:g}). The linear model's velocity ω × (X − c) is an infinitesimal "
            "rotation, of zero linear strain: its points move on straight lines and the area grows as 1 + (ω t)², "
            "≈ 10.9 after half a turn.")
    nums = {r["material"]: {k: r[k] for k in ("energy_drift", "angular_drift", "momentum_drift", "half_turn_area",
                                              "its", "seconds")} for r in rows}
    body = f"<p>{done} in {sum(r['seconds'] for r in rows):.0f} s (files in <code>finite_strain/</code>).</p>"
    return Entry("finite_strain_spin", text, Verdict.of(ok), says=says, png="finite_strain/spin.png", head=HEAD,
                 html=body, numbers=nums, section="finite_strain")


def patch_entry(rows, done):
    """The homogeneous stretch against the closed forms, and the small-strain limit."""
    ok = all(r["err_u"] <= SPIN_TOL and r["err_reaction"] <= SPIN_TOL and abs(r["slope"] - 1) <= 0.05 for r in rows)
    text = ("Ours (P2/P1, a distorted 4 × 4 mesh, 10 steps to the stretch 1.5): "
            + "; ".join(f"{r['material']}: u exact to {r['err_u']:.0e}, the reaction the closed form to "
                        f"{r['err_reaction']:.0e} at every step ({r['final_reaction']:.3f} against the linear "
                        f"{r['linear_reaction']:.3f} at the end), departing from the linear model by "
                        f"{r['departures'][0] / (0.95 * r['strains'][0]):+.3f} × the strain at 1e-3 (fitted slope "
                        f"{r['slope']:.3f})" for r in rows) + ". ")
    says = ("A block stretched homogeneously, F = diag(1 + G t, 1) prescribed on its sides (plane strain): the "
            "exact solution is that F everywhere, on any mesh, and the reaction is each material's energy–momentum "
            "stress between the step's stretches in closed form (the finite-strain patch test, to round-off). At "
            "small strains e every material is the linear model plus O(e): the first-order coefficient of "
            "P_xx / ((λ + 2μ) e) − 1 is +3/2 for Saint Venant–Kirchhoff and −(μ + 3λ/2)/(λ + 2μ) = −1 for this "
            "neo-Hookean (λ = 2, μ = 1).")
    table = html_table(["material", "max |u − u_exact|", "reaction vs closed form", "departure at e = 1e-3, 1e-2, "
                        "1e-1", "fitted slope"],
                       [(r["material"], f"{r['err_u']:.1e}", f"{r['err_reaction']:.1e}",
                         ", ".join(f"{d:+.2e}" for d in r["departures"]), f"{r['slope']:.3f}") for r in rows])
    nums = {"rows": rows}
    return Entry("finite_strain_patch", text, Verdict.of(ok), says=says, html=table + f"<p>{done}.</p>",
                 numbers=nums, section="finite_strain")


def rolling_entry(rows, done):
    """The disc rolling one revolution on a frictional plane."""
    nh = _by(rows, "neo-hookean")
    lin = _by(rows, "linear")[0]
    ok = all(abs(r["advance_per_revolution"] - 1) <= ROLL_TOL and r["moved_unslipping"] == 0 and r["balance"] <= SPIN_TOL
             for r in nh)
    drifts = ", ".join(f"{100 * r['energy_drift']:.2f} % at dt = {r['dt']:g} s" for r in nh)
    first = nh[0]
    text = (f"Ours (neo-Hookean, level 1, P2/P1, Coulomb μ = {fs.ROLL_MU:g}, v = {fs.ROLL_V:g} mm/s): in one "
            f"revolution the centre advances {first['advance_per_revolution']:.4f} × 2πR per turn (the contact "
            f"slides in {first['slip_steps']} of {first['steps']} steps; every vertex in stick keeps its place "
            f"exactly), and the energy balance E^(n+1) − E^n = λ_N·ΔU_N − (friction's dissipation) holds at every step "
            f"to {max(r['balance'] for r in nh):.0e} of E0. The energy itself moves by at most {drifts}: the work of "
            f"the vertices' arrivals on the plane (λ_N·ΔU_N ≠ 0 when U^n is below the plane at the half-step "
            f"constraint), which falls with dt. The linear model does not roll: it turns {lin['turns']:.2f} of a "
            f"revolution, advances {lin['advance']:.2f} × 2πR and friction takes {100 * lin['energy_drift']:.1f} % of "
            f"its energy, its contact vertices dragged along the plane by the infinitesimal rotation's straight "
            f"lines. ")
    says = ("A disc (R = 20 mm, the paper's material, gravity) started rolling at ωR = v on a plane with Coulomb "
            "friction: rolling without slipping, its centre advances 2πR per revolution (the discrete disc, a "
            "polygon of vertices compressed by its weight, a little less), the contact point's velocity is zero "
            f"in stick, and no energy is dissipated. The check: the advance per revolution within {100 * ROLL_TOL:g} % "
            "of 2πR, no vertex in stick moving, the step's energy balance to the Newton tolerance.")
    table = html_table(["material", "dt (s)", "steps", "turns", "advance / 2πR per turn", "max |E − E0| / E0",
                        "energy balance", "slipping steps", "Newton its / step", "run time"],
                       [(r["material"], f"{r['dt']:g}", r["steps"], f"{r['turns']:.4f}",
                         f"{r['advance_per_revolution']:.4f}", f"{r['energy_drift']:.2e}", f"{r['balance']:.1e}",
                         r["slip_steps"], f"{r['its']:.2f}", f"{r['seconds']:.0f} s") for r in rows])
    nums = {"rows": [{k: v for k, v in r.items() if not isinstance(v, (list, dict))} for r in rows]}
    return Entry("finite_strain_rolling", text, Verdict.of(ok), says=says, png="finite_strain/rolling.png",
                 html=table + f"<p>{done}.</p>", numbers=nums, section="finite_strain")


def ball_entry(rows, done):
    """The soft ball against Hertz as its speed grows."""
    slow = min(r["speed"] for r in rows)
    nh_slow = [r for r in _by(rows, "neo-hookean") if r["speed"] == slow][0]
    within = [abs(nh_slow[k]) <= HERTZ_TOL for k in ("err_t_c", "err_F_max")]
    fast = max(rows, key=lambda r: (r["speed"], r["material"] == "neo-hookean"))
    lin_fast = [r for r in _by(rows, "linear") if r["speed"] == fast["speed"]][0]
    text = (f"Ours (level {nh_slow['level']}, P2/P1, dt = t_c / {fs.BALL_STEPS}): at {slow:g} mm/s the neo-Hookean "
            f"ball's t_c is {100 * nh_slow['err_t_c']:+.1f} % and F_max {100 * nh_slow['err_F_max']:+.1f} % from "
            f"Hertz. At {fast['speed']:g} mm/s (δ_max ≈ R / {1 / fast['delta_over_R']:.0f}) the neo-Hookean F_max is "
            f"{100 * fast['err_F_max']:+.1f} % and the linear model's {100 * lin_fast['err_F_max']:+.1f} %: the "
            f"departure from Hertz as the speed grows is the impact's dynamics and the large indentation's geometry, "
            f"common to both; the material law adds {100 * abs(fast['F_max'] / lin_fast['F_max'] - 1):.1f} %. ")
    says = ("Hertz's quasi-static impact of a sphere (R = 20 mm, E = 10 N/mm², ν = 0.3, ρ = 1000 kg/m³) on a rigid "
            "plane assumes small strains; at low speed the hyperelastic ball must agree with it (the check: t_c and "
            f"F_max within {100 * HERTZ_TOL:g} % at the slowest speed), and the departure grows with the speed.")
    table = html_table(["material", "v (mm/s)", "δ_max / R (Hertz)", "dt (s)", "dim W", "t_c", "F_max", "δ_max",
                        "max |E − E0| / E0", "run time"],
                       [(r["material"], f"{r['speed']:g}", f"{r['delta_over_R']:.3f}", f"{r['dt']:g}", r["dim_W"],
                         f"{100 * r['err_t_c']:+.1f} %", f"{100 * r['err_F_max']:+.1f} %",
                         f"{100 * r['err_delta_max']:+.1f} %", f"{r['energy_max_dev']:.1e}", f"{r['seconds']:.0f} s")
                        for r in rows])
    note = html.escape("The ball's mesh is refined for the Hertz contact radius a of its own speed (the ball "
                       "problem's levels), so every speed is resolved alike. Errors against Hertz: t_c is resolved "
                       "to dt.")
    nums = {"rows": [{k: v for k, v in r.items() if k != "hertz"} for r in rows]}
    return Entry("finite_strain_ball", text, Verdict.of(all(within), any(within)), says=says, png="finite_strain/ball_speed.png",
                 html=table + f"<p>{note} {done}.</p>", numbers=nums, section="finite_strain")
