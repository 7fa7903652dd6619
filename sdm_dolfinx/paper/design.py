"""The study: which runs reproduce the paper's figures and tables, and their TOML files.

A :class:`Run` is a problem name, its parameter values and the run options of
:func:`sdm_dolfinx.run.simulate`; :func:`make_study` lays out the runs behind every figure
(the full study with the paper's parameters, or the quick smoke test), and
:func:`paper_configurations` writes the full study's runs as the ``data/paper/*.toml``
files that ``python -m sdm_dolfinx PROBLEM --config FILE`` reads.
"""
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from sdm_dolfinx.study.run_spec import PAPER_MESHES, PAPER_TABLE2, Run, config_text  # noqa: F401 (re-exported)
from sdm_dolfinx.errors import shown
from sdm_dolfinx.problems.disc_mesh import LEVELS
from sdm_dolfinx.run import num_steps

# ----------------------------------------------------------------------------- the paper
#: the pairs of Figs. 2-6 in the paper's order, and their figure numbers
MEMBRANE_PAIRS = {"P1+/P0": 2, "P1/P0": 3, "P1/P1": 4, "P1+/P1": 5, "P2/P1": 6}
#: backward Euler figures
BE_PAIRS = {"P1+/P0": 7, "P1/P0": 8}
#: well-posed (condition (7) proved or observed) or not, as the paper says
WELL_POSED = {"P1+/P0": True, "P1/P0": False, "P1/P1": False, "P1+/P1": True, "P2/P1": True, "P2/P2": False}
PAPER_RATE = 0.69
#: the final time of the disc runs in the paper's program (its ``.param`` file: T = 0.02)
PAPER_T = 0.02
#: where the paper's meshes are looked for, in this order (the first folder holding them wins):
#: ``$SDM_GETFEM_MESHES``, then ``shared/data/getfem-disc-meshes`` beside the repository or beside one
#: of its parent folders (CI lays ``shared/`` beside its clone; they are GetFEM's, LGPL: not copied
#: into this project; docs/disc_meshes.md says where to get them)
PAPER_MESH_DIRS = (os.environ.get("SDM_GETFEM_MESHES"),
                   *(p / "shared" / "data" / "getfem-disc-meshes" for p in Path(__file__).resolve().parents[3:]))

#: the paper's program (GetFEM): the "regular simplices" mesh of the unit square, which is
#: dolfinx's left_right diagonal pattern, and the midpoint scheme applied to the (U, V) system
#: (4) with the consistent C of a P1 velocity (never forming M)
MEMBRANE_DIAGONAL = "left_right"

def getfem_steps(T, dt):
    """The number of steps the paper's program takes to reach ``T``: GetFEM's
    ``mixed_dynamic_friction.cc`` runs ``t = 0; while (t <= T) { step; t += dt; }`` in double
    precision, so one step past T whenever the accumulated t falls just short of T: for
    T = 0.02, dt = 8e-4, 4e-4, 2e-4, 1e-4 give 26, 51, 101, 201 steps (t = 0.0208 ... 0.0201),
    dt = 5e-5 and 2.5e-5 exactly 400 and 800 (the sum overshoots 0.02 by round-off).

    Raises:
        ValueError: ``dt`` or ``T`` not positive and finite, or more than 1e7 steps.
    """
    if not (0 < dt < math.inf and 0 < T < math.inf) or T / dt > 1e7:
        raise ValueError(f"getfem_steps needs 0 < dt, T < inf and T / dt <= 1e7 (got T = {shown(T)}, dt = {shown(dt)})")
    t, n = 0.0, 0
    while t <= T:
        t += dt
        n += 1
    return n


def paper_mesh_dir(dirs=PAPER_MESH_DIRS):
    """The first folder of ``dirs`` holding every file of :data:`PAPER_MESHES`, or None."""
    for d in dirs:
        if d and all((Path(d) / f).is_file() for f in PAPER_MESHES.values()):
            return Path(d)
    return None


def slug(pair):
    """A pair's name in file names: ``P1+/P0`` -> ``P1plus-P0``."""
    return pair.replace("/", "-").replace("+", "plus")


# --------------------------------------------------------------------------------- runs
def _write_every(steps, states=100):
    return max(1, steps // states)


def _divisor_every(steps, states):
    """The largest divisor of ``steps`` at most ``steps // states``: about ``states`` stored
    states, one of them at step ``steps`` exactly."""
    k = max(1, steps // states)
    while steps % k:
        k -= 1
    return k


def _mass(pair):
    """The paper's program uses the consistent C of a P1 velocity (P1+/P1, P2/P1)."""
    return {"mass": "consistent"} if pair.endswith("/P1") and not pair.startswith("P1/") else {}


def membrane_run(pair, N, dt, T, scheme="midpoint", write_every=None):
    """The membrane on the paper's mesh (h = 1/N)."""
    k = write_every or _write_every(num_steps(T, dt))
    sch = "mp" if scheme == "midpoint" else "be"
    name = f"membrane_{slug(pair)}_{sch}_N{N}_dt{dt:.6g}_T{T:g}_w{k}"
    return Run(name, "membrane", {"N": N, "diagonal": MEMBRANE_DIAGONAL},
               {"pair": pair, **_mass(pair), "scheme": scheme, "dt": float(dt), "T": float(T), "write_every": k})


def disc_run(pair, level, dt, T=0.02, write_every=None, mesh_file=None):
    """The falling disc on our gmsh mesh ``level`` or, given ``mesh_file``, on that mesh (one
    of the paper's GetFEM meshes; ``level`` is then unused)."""
    k = write_every or _write_every(num_steps(T, dt))
    if mesh_file is None:
        mesh, params = f"L{level}", {"level": level}
    else:
        mesh, params = "getfem-" + Path(mesh_file).stem.replace("disc_P2_", ""), {"mesh_file": str(mesh_file)}
    name = f"disc_{slug(pair)}_{mesh}_dt{dt:.6g}_T{T:g}_w{k}"
    return Run(name, "disc", params,
               {"pair": pair, **_mass(pair), "scheme": "midpoint", "dt": float(dt), "T": float(T), "write_every": k})


def conv_run(row, mesh_file=None):
    """Table 2's row ``row`` (P2/P1, dt = 8e-4 / 2^(row - 1)) on gmsh level ``row`` or on
    ``mesh_file``, run for the paper program's step count (:func:`getfem_steps`: one step past
    t = 0.02 for rows 1-4) with the state at t = 0.02 (step ``num_steps(0.02, dt)``) stored
    too, so that one run gives both conventions of Table 2."""
    dt = 8e-4 / 2 ** (row - 1)
    n, n02 = getfem_steps(PAPER_T, dt), num_steps(PAPER_T, dt)
    T = float(f"{n * dt:.12g}")                   # 0.0208, not 0.020800000000000003: still n steps
    return disc_run("P2/P1", row, dt, T, write_every=_divisor_every(n02, 20), mesh_file=mesh_file)


# -------------------------------------------------------------------------------- study
@dataclass
class Study:
    """The runs behind each figure (same run objects where figures share a run)."""
    quick: bool
    membrane_T: float
    pairs: dict = field(default_factory=dict)       # pair -> {dt: Run} (midpoint, N = 10)
    be: dict = field(default_factory=dict)          # pair -> {dt: Run}
    fig9: dict = field(default_factory=dict)        # N -> Run
    fig10: dict = field(default_factory=dict)       # pair -> {N: Run}
    fig11: dict = field(default_factory=dict)       # pair -> {N: {ratio: Run}}
    fig1: Optional[Run] = None
    disc: dict = field(default_factory=dict)        # pair -> {dt: Run} (level 1)
    conv: dict = field(default_factory=dict)        # level -> Run (gmsh meshes; the finest is the reference)
    conv_getfem: dict = field(default_factory=dict)  # Table 2 row -> Run on the paper's own mesh (rows 1-4)
    getfem_mesh_dir: Optional[Path] = None           # where the paper's meshes were found (None: not found)
    conv_levels_shown: tuple = ()

    def runs(self):
        """Every run once, cheapest figures first."""
        seen = {}
        groups = [*self.pairs.values(), *self.be.values(), self.fig9, *self.fig10.values(),
                  *(dd for d in self.fig11.values() for dd in d.values())]
        for group in groups:
            for r in group.values():
                seen.setdefault(r.name, r)
        seen.setdefault(self.fig1.name, self.fig1)
        for d in self.disc.values():
            for r in d.values():
                seen.setdefault(r.name, r)
        for lev in sorted(self.conv):
            if lev in self.conv_getfem:
                seen.setdefault(self.conv_getfem[lev].name, self.conv_getfem[lev])
            seen.setdefault(self.conv[lev].name, self.conv[lev])
        return list(seen.values())


def make_study(quick=False, disc_max_level=None):
    """The runs of the full study (the paper's parameters) or of the quick one."""
    T = 0.5 if quick else 0.8          # quick: the first impact (t ~ 0.26) and the rebound
    s = Study(quick=quick, membrane_T=T)
    dts = (1e-2, 1e-3) if quick else (1e-2, 1e-3, 1e-4)
    for pair in MEMBRANE_PAIRS:
        s.pairs[pair] = {dt: membrane_run(pair, 10, dt, T) for dt in dts}
    for pair in BE_PAIRS:
        s.be[pair] = {dt: membrane_run(pair, 10, dt, T, "backward-euler") for dt in dts}
    for N in ((10, 20) if quick else (10, 20, 40, 80)):
        s.fig9[N] = membrane_run("P1/P0", N, 1e-3, T, "backward-euler")
    ratio10 = 5e-3
    for pair in ("P1+/P0", "P2/P1"):
        s.fig10[pair] = {N: membrane_run(pair, N, ratio10 / N, T) for N in ((2, 4, 8) if quick else (2, 4, 8, 16))}
        Ns = (2, 4, 8) if quick else (4, 8, 16, 32)
        ratios = (0.04, 0.01, 0.005) if quick else (0.08, 0.04, 0.02, 0.01, 0.005)
        s.fig11[pair] = {N: {r: membrane_run(pair, N, r / N, T) for r in ratios} for N in Ns}
    s.fig1 = (s.pairs["P1+/P0"][1e-3] if quick else membrane_run("P1+/P0", 20, 1e-3, 0.4, write_every=5))
    for pair in ("P2/P2", "P2/P1"):
        s.disc[pair] = {dt: disc_run(pair, 1, dt) for dt in (1e-4, 1e-5)}
    top = disc_max_level or (3 if quick else 6)
    if top not in LEVELS or top < 2:
        raise ValueError(f"--disc-max-level must be one of {', '.join(map(str, sorted(LEVELS)[1:]))}")
    for lev in range(1, top + 1):
        s.conv[lev] = conv_run(lev)
    s.getfem_mesh_dir = paper_mesh_dir()
    if s.getfem_mesh_dir is not None:                 # the paper's meshes, on the rows below the reference
        s.conv_getfem = {row: conv_run(row, s.getfem_mesh_dir / f) for row, f in PAPER_MESHES.items() if row < top}
    # the paper shows three solutions a factor 4 apart in dt (levels 2, 4, 6 of Table 2)
    s.conv_levels_shown = (top - 4, top - 2, top) if top >= 5 else tuple(range(1, top + 1))
    return s


# ------------------------------------------------------------------- data/paper/*.toml
def _dt(dt):
    return f"{dt:.0e}".replace("e-0", "e-") if float(f"{dt:.0e}") == dt else f"{dt:g}"


def paper_configurations(study=None):
    """The runs of the full study (the paper's figures and tables) as TOML configuration
    files: file name -> text. ``data/paper/`` holds exactly these (a test checks it)."""
    s = study or make_study()
    out = {}

    def put(name, run, title):
        if run.problem == "membrane":
            o, p = run.options, run.params
            mesh = f"h = 1/{p['N']} ({p['diagonal']} diagonals)"
            mass = ", consistent C (the (U, V) system (4))" if o.get("mass") == "consistent" else ""
            title = f"{title}: {o['pair']}{mass}, {o['scheme']}, {mesh}, dt = {o['dt']:g}"
        out[name + ".toml"] = config_text(run, title)

    put("membrane_fig01_P1plus-P0_N20", s.fig1, "Fig. 1 (the membrane during its first impact)")
    for pair, fig in MEMBRANE_PAIRS.items():
        for dt, run in s.pairs[pair].items():
            put(f"membrane_fig{fig:02d}_{slug(pair)}_dt{_dt(dt)}", run, f"Fig. {fig}")
    for pair, fig in BE_PAIRS.items():
        for dt, run in s.be[pair].items():
            put(f"membrane_fig{fig:02d}_{slug(pair)}_be_dt{_dt(dt)}", run, f"Fig. {fig}")
    for N, run in s.fig9.items():
        put(f"membrane_fig09_P1-P0_be_N{N}", run, "Fig. 9")
    for pair, runs in s.fig10.items():
        for N, run in runs.items():
            put(f"membrane_fig10_{slug(pair)}_N{N}", run, "Fig. 10 (dt/h fixed)")
    for pair, by_N in s.fig11.items():
        for N, runs in by_N.items():
            for ratio, run in runs.items():
                put(f"membrane_fig11_{slug(pair)}_N{N}_dt-over-h{ratio:g}", run, f"Fig. 11 (dt/h = {ratio:g})")
    for pair, fig in (("P2/P2", 14), ("P2/P1", 15)):
        for dt, run in s.disc[pair].items():
            mass = ", consistent C" if run.options.get("mass") == "consistent" else ", standard mass"
            put(f"disc_table1_fig{fig}_{slug(pair)}_dt{_dt(dt)}", run,
                f"Table 1 and Fig. {fig}: the disc, {pair}{mass}, midpoint, level 1 (h ~ 2 mm), dt = {dt:g} s")
    for lev, run in s.conv.items():
        dt, h, dofs = PAPER_TABLE2[lev][:3]
        put(f"disc_table2_level{lev}", run,
            f"Table 2, line {lev} (Fig. 16): P2/P1, consistent C, midpoint, h = {h:g} mm ({dofs} dofs in the paper), "
            f"dt = {dt:g} s, {run.steps} steps as the paper's program ran them"
            + (f" (to t = {run.options['T']:g} s; the state at t = 0.02 s is stored too)"
               if run.steps != num_steps(PAPER_T, dt) else ""))
    # the runs on the paper's own meshes (s.conv_getfem) are not written: their mesh files are not
    # part of the repository, and a configuration naming this machine's folder would not be portable
    return out
