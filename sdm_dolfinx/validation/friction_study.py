"""The friction runs of the report (not in the paper): the disc rolling and sliding
down an incline and the elastic block sliding to a stop, against their rigid-body closed
forms, and the disc's oblique impact with a sticking and a sliding friction coefficient.

Each is a :class:`~sdm_dolfinx.study.run_spec.Run` of a built-in problem with the run options
``friction``, ``mu`` or ``tresca_threshold``; :func:`friction_runs` lays them out for the
full or the quick study, :func:`configurations` writes them as ``data/validation``'s TOML files.
"""
from dataclasses import dataclass, field

from sdm_dolfinx import problems
from sdm_dolfinx.study.run_spec import Run, config_text
from sdm_dolfinx.problems.disc_mesh import LEVELS

# ------------------------------------------------------------------ the disc on the incline
#: the incline's angle (degrees): the disc rolls without slipping when mu >= tan(30°)/3 = 0.192
THETA = 30.0
#: the two friction coefficients: rolling (mu >= 0.192) and sliding (mu < 0.192)
INCLINE_MU = {"rolling": 0.5, "sliding": 0.1}
#: how long the disc runs down the incline (s): 0.16 mm of rolling, much less than the level-1
#: mesh size (2 mm), so the contact stays at point A
INCLINE_T = 0.01
#: dt per mesh level, halved with h (level 1: 1e-4 s, the disc's default)
INCLINE_DT = {1: 1e-4, 2: 5e-5, 3: 2.5e-5}

# ------------------------------------------------------------------------- the sliding block
#: Coulomb's coefficient of the block (docs/friction_problems.md: stops at 34.0 ms after 1.70 mm)
BLOCK_MU = 0.3
#: the block's defaults (problems/block.py), stated so that a change of default makes the run stale
BLOCK_PARAMS = {"width": 20.0, "height": 10.0, "nx": 10, "ny": 5, "E": 1000.0, "nu": 0.0, "rho": 1e-6,
                "gravity": 9810.0, "v0": 100.0, "start": "equilibrium"}


def block_threshold(mu=BLOCK_MU, p=BLOCK_PARAMS):
    """Tresca's threshold s (N/mm^2) that stops the block as Coulomb's ``mu`` does: s L = mu m g."""
    mass = p["rho"] * p["width"] * p["height"]
    return float(f"{mu * mass * p['gravity'] / p['width']:.12g}")


# ---------------------------------------------------------------------- the oblique impact
#: horizontal initial velocity (mm/s) of the paper's disc (v0 = -1000 mm/s from 10 mm): the impact
#: is 42° from the normal, and a rigid disc would slide through the whole impact when mu <
#: vx0 / (3 J_N / m) ~ 0.15 (J_N ~ 2 m |v_n| the normal impulse), and stick soon for mu = 1
IMPACT_VX0 = 1000.0
#: the sticking and the sliding case
IMPACT_MU = {"sticking": 1.0, "sliding": 0.1}
#: the runs stop 1.3 ms after the disc leaves the foundation (contact from 9.6 to 15.7 ms)
IMPACT_T = 0.017


@dataclass
class FrictionStudy:
    """The friction runs: ``incline[regime][level]``, ``block[law]``, ``impact[case]``."""
    quick: bool
    incline: dict = field(default_factory=dict)
    block: dict = field(default_factory=dict)
    impact: dict = field(default_factory=dict)

    def runs(self):
        """Every run once, cheapest first."""
        return ([*self.block.values()] + [r for d in self.incline.values() for r in d.values()]
                + [*self.impact.values()])


def has_equilibrium_start():
    """True when the disc declares ``start`` with an ``equilibrium`` choice (a disc resting on the
    incline from t = 0, no vertical vibration); otherwise the incline runs start just touching."""
    try:
        p = problems.get("disc").param("start")
    except KeyError:
        return False
    return "equilibrium" in (p.choices or ())


def _disc_options(dt, T, mu, steps_between_states):
    return {"pair": "P2/P1", "scheme": "midpoint", "dt": float(dt), "T": float(T), "friction": "coulomb",
            "mu": float(mu), "write_every": steps_between_states}


def incline_run(regime, level):
    """The disc at rest on the incline at :data:`THETA` with ``INCLINE_MU[regime]``, ``level``."""
    params = {"level": level, "height": 0.0, "v0": 0.0, "gravity_angle": THETA}
    if has_equilibrium_start():
        params["start"] = "equilibrium"
    dt = INCLINE_DT[level]
    steps = round(INCLINE_T / dt)
    return Run(f"friction_incline_{regime}_L{level}_dt{dt:g}", "disc", params,
               _disc_options(dt, INCLINE_T, INCLINE_MU[regime], max(1, steps // 10)))


def block_run(law):
    """The default block sliding from its equilibrium: Coulomb :data:`BLOCK_MU` or the Tresca
    threshold of the same stop (:func:`block_threshold`)."""
    law_opt = {"mu": BLOCK_MU} if law == "coulomb" else {"tresca_threshold": block_threshold()}
    return Run(f"friction_block_{law}", "block", dict(BLOCK_PARAMS),
               {"pair": "P2/P1", "scheme": "midpoint", "dt": 1e-4, "T": 0.04, "friction": law, **law_opt,
                "write_every": 40})


def impact_run(case, quick):
    """The paper's disc with vx0 = :data:`IMPACT_VX0`, fields written every 1e-4 s for the
    stick/slip zones: level 1, dt = 1e-4 s (quick) or level 3, dt = 2.5e-5 s (full)."""
    level, dt, k = (1, 1e-4, 1) if quick else (3, 2.5e-5, 4)
    mu = IMPACT_MU[case]
    return Run(f"friction_impact_mu{mu:g}_vx{IMPACT_VX0:g}_L{level}_dt{dt:g}", "disc",
               {"level": level, "vx0": IMPACT_VX0}, _disc_options(dt, IMPACT_T, mu, k))


def friction_runs(quick=False):
    """The friction runs of the full study (incline on levels 1-3) or of the quick one (level 1)."""
    fs = FrictionStudy(quick=quick)
    levels = (1,) if quick else tuple(lev for lev in INCLINE_DT if lev in LEVELS)
    fs.incline = {regime: {lev: incline_run(regime, lev) for lev in levels} for regime in INCLINE_MU}
    fs.block = {law: block_run(law) for law in ("coulomb", "tresca")}
    fs.impact = {case: impact_run(case, quick) for case in IMPACT_MU}
    return fs


def configurations(fs=None):
    """The friction runs of the full study as ``data/validation`` TOML files: file name (starting
    with the problem's name) -> text."""
    return {name + ".toml": config_text(run, title, "friction (not in the paper)")
            for name, (run, title) in _titles(fs or friction_runs()).items()}


def _titles(fs):
    """File stem -> (run, title) of every friction run."""
    out = {}
    for regime, by_level in fs.incline.items():
        for lev, run in by_level.items():
            out[f"disc_friction_incline_{regime}_level{lev}"] = (
                run, f"the disc {regime} down a {THETA:g}° incline, Coulomb mu = {INCLINE_MU[regime]:g}, level {lev}, "
                     f"dt = {run.options['dt']:g} s")
    for law, run in fs.block.items():
        what = f"mu = {BLOCK_MU:g}" if law == "coulomb" else f"threshold {block_threshold():g} N/mm^2"
        out[f"block_friction_{law}"] = (run, f"the elastic block sliding to a stop, {law} friction {what}")
    for case, run in fs.impact.items():
        out[f"disc_friction_impact_{case}"] = (
            run, f"the disc's oblique impact (vx0 = {IMPACT_VX0:g} mm/s), Coulomb mu = {IMPACT_MU[case]:g} ({case})")
    return out
