"""Finite strain (run option ``material``): the energy-momentum midpoint scheme conserves the energy and
both momenta of a free body to the tolerance of its Newton iterations, a homogeneous deformation is
reproduced to round-off on a distorted mesh with the closed-form stress of each material, a problem's
own psi(C) runs like the built-in law it writes, and what the hyperelastic step does not take is refused
in one line; with contact and prescribed motion, the pushed block's force is each material's closed form,
and the linear model's at small strains.

Runs on 1 and 2 ranks; every number checked is an exact identity of the scheme or a closed form."""
import warnings
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import DirichletPart, Problem, simulate
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.run.finite_strain_step import RTOL
from sdm_dolfinx.run.options import RunInputError
from sdm_dolfinx.validation.finite_strain import LAM, MU, OMEGA, DT, free_body, area as deformed_area
from sdm_dolfinx.validation.finite_strain import spinning_square as validation_square
from sdm_dolfinx.validation.finite_strain_patch import RATE, closed_form_reaction, small_strain, stretched_block

COMM = MPI.COMM_WORLD


def svk_psi(C):
    """Saint Venant-Kirchhoff written by hand, as a problem file would (``material problem``)."""
    E = 0.5 * (C - ufl.Identity(ufl.shape(C)[0]))
    return 0.5 * LAM * ufl.tr(E) ** 2 + MU * ufl.inner(E, E)


def body(msh, u0, v0, parts=(), psi=None, columns=("momentum_x", "momentum_y")):
    """A free body of density 1 with Hooke's a(u, w) of (LAM, MU) (:func:`~sdm_dolfinx.validation.finite_strain.free_body`)."""
    return free_body(msh, u0, v0, parts, psi, LAM, MU, columns)


def spinning_square(psi=None):
    """The unit square spinning about its centre at OMEGA plus a small deformation rate, from u0 = 0."""
    return validation_square(psi, comm=COMM)


def drift(column, scale):
    """max |column - column[0]| / scale."""
    return float(np.max(np.abs(column - column[0]))) / scale


@pytest.mark.parametrize("material", ["svk", "neo-hookean", "problem"])
def test_spinning_square_conserves_energy_and_momenta(material):
    """Three revolutions (188 steps of 0.05, omega = 2, stretches up to ~10 %): the energy, both linear
    momenta and the angular momentum stay at their initial values to the Newton tolerance (the residual
    is 1e-10 of the step's scale; every step of the scheme conserves them exactly at the solution)."""
    r = simulate(spinning_square(svk_psi if material == "problem" else None), pair="P2/P1", material=material,
                 dt=DT, T=9.4)
    d = r.timeseries
    E0, L0 = d["energy"][0], d["angular_momentum"][0]
    assert L0 > 0.25        # omega I_z = 1/3 for the continuum; the lumped P1 velocity's M has less inertia
    assert drift(d["energy"], E0) < 1e3 * RTOL
    assert drift(d["angular_momentum"], abs(L0)) < 1e3 * RTOL
    p_scale = OMEGA * 0.5           # |M Vbar| of the rotation's velocities, for the zero total momentum
    assert drift(d["momentum_x"], p_scale) < 1e3 * RTOL and drift(d["momentum_y"], p_scale) < 1e3 * RTOL
    assert d["potential"].max() > 1e-3 * E0        # the body does deform (a test of a rigid motion would be idle)
    assert np.all(d["nonlinear_its"][1:] >= 1) and d["nonlinear_its"].max() <= 8


def area(result):
    """The area of the deformed body at the run's final state."""
    return deformed_area(result.discretisation, result.U.array)


def test_linear_model_spins_into_a_swollen_body():
    """The same spin, half a revolution, with the linear model: its velocity omega x (X - c) is an
    infinitesimal rotation, of zero linear strain, so every point moves on a straight line and the square's
    area grows as 1 + (omega t)^2 (11 at theta = pi) at no elastic energy; the hyperelastic run keeps its
    area within the centrifugal stretch."""
    half = round(np.pi / OMEGA / DT) * DT
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        lin = simulate(spinning_square(), pair="P2/P1", dt=DT, T=half)
    if COMM.rank == 0:                  # the linear-range warning (rank 0) names the remedy
        assert any("material svk or neo-hookean" in str(w.message) for w in caught)
    svk = simulate(spinning_square(), pair="P2/P1", material="svk", dt=DT, T=half)
    assert area(lin) == pytest.approx(1 + (OMEGA * half) ** 2, rel=0.01)
    assert area(svk) == pytest.approx(1.0, abs=0.1)


def test_spinning_cube_conserves_angular_momentum():
    """A cube spinning about z (P2/P1 tetrahedra), 40 steps: energy and the three components of the
    angular momentum to the Newton tolerance."""
    msh = dmesh.create_unit_cube(COMM, 2, 2, 2)
    v0 = lambda x: np.array([-OMEGA * (x[1] - 0.5), OMEGA * (x[0] - 0.5) + 0.1 * (x[2] - 0.5) ** 2,  # noqa: E731
                             0.05 * (x[0] - 0.5)])
    p = body(msh, lambda x: np.zeros((3, x.shape[1])), v0, columns=())
    d = simulate(p, pair="P2/P1", material="neo-hookean", dt=DT, T=40 * DT).timeseries
    E0 = d["energy"][0]
    assert drift(d["energy"], E0) < 1e3 * RTOL
    Lz = d["angular_momentum_z"]
    assert Lz[0] > 0.2      # omega I_z = 1/3 for the continuum (the coarse mesh's M has less)
    for axis in "xyz":
        assert drift(d[f"angular_momentum_{axis}"], abs(Lz[0])) < 1e3 * RTOL


@pytest.mark.parametrize("scheme", ["newmark", "hht", "backward-euler"])
def test_comparison_schemes_do_not_conserve_the_energy(scheme):
    """The schemes offered for comparison (the stress at the step's end: Newmark, HHT with alpha = -0.1, backward
    Euler) on the same three revolutions: the linear momenta stay constant (the internal force of a rigid
    translation is zero), but the energy and the angular momentum do not, by far more than the energy-momentum
    scheme's 5e-10 (measured: Newmark 0.60 % and 0.35 %, HHT 1.3 % and 0.49 %, backward Euler 77 % and 53 %,
    the last two dissipating)."""
    d = simulate(spinning_square(), pair="P2/P1", material="neo-hookean", scheme=scheme, dt=DT, T=9.4).timeseries
    E0, L0 = d["energy"][0], d["angular_momentum"][0]
    p_scale = OMEGA * 0.5
    assert drift(d["momentum_x"], p_scale) < 1e3 * RTOL and drift(d["momentum_y"], p_scale) < 1e3 * RTOL
    assert drift(d["energy"], E0) > 1e-3 and drift(d["angular_momentum"], abs(L0)) > 1e-3
    if scheme != "newmark":
        assert d["energy"][-1] < E0


@pytest.mark.parametrize("scheme", ["newmark", "hht", "backward-euler"])
def test_comparison_schemes_have_the_linear_limit(scheme):
    """At small amplitudes a hyperelastic run is its scheme's linear run plus O(amplitude): a square vibrating
    from the velocity a (sin(pi x) y, cos(pi y) x), 40 steps, a = 1e-3 and 1e-4: the neo-Hookean u_probe departs
    from the linear one's by O(a) relative (the ratio of the two departures 10 within 20 %, and below 5e-3 at
    a = 1e-3; measured 2.2e-3). A wrong end-of-step force or HHT term would leave an O(1) difference."""
    dev = []
    for a in (1e-3, 1e-4):
        v0 = lambda x, a=a: a * np.array([np.sin(np.pi * x[0]) * x[1], np.cos(np.pi * x[1]) * x[0]])  # noqa: E731
        runs = {m: simulate(body(dmesh.create_unit_square(COMM, 4, 4), lambda x: np.zeros((2, x.shape[1])), v0),
                            pair="P2/P1", material=m, scheme=scheme, dt=0.05, T=2.0).timeseries["u_probe"]
                for m in ("linear", "neo-hookean")}
        dev.append(np.max(np.abs(runs["neo-hookean"] - runs["linear"])) / np.max(np.abs(runs["linear"])))
    assert dev[0] < 5e-3 and dev[0] / dev[1] == pytest.approx(10.0, rel=0.2), dev


def test_modified_newton_reaches_the_same_steps():
    """newton modified (the step's first tangent) converges to newton full's steps on the spin, to the
    Newton tolerance, with one tangent per step and more iterations."""
    full = simulate(spinning_square(), pair="P2/P1", material="svk", dt=DT, T=20 * DT).timeseries
    other = simulate(spinning_square(), pair="P2/P1", material="svk", newton="modified", dt=DT, T=20 * DT).timeseries
    assert np.all(other["tangents"][1:] == 1)
    assert other["nonlinear_its"][1:].sum() > full["nonlinear_its"][1:].sum()
    assert np.max(np.abs(other["energy"] - full["energy"])) < 1e3 * RTOL * full["energy"][0]
    assert np.max(np.abs(other["u_probe"] - full["u_probe"])) < 1e-7


# ------------------------------------------------------------------ the homogeneous patch test
#: the rate of the uniaxial stretch: u_x = G t x, lambda(t) = 1 + G t (validation.finite_strain_patch)
G = RATE


@pytest.mark.parametrize("material", ["svk", "neo-hookean"])
def test_homogeneous_stretch_is_reproduced_to_round_off(material):
    """The finite-strain patch test: 10 steps of 0.1 to a stretch of 1.5 on a distorted mesh. Every dof
    holds u = (G t x, 0) to round-off, and the reaction on the stretched side is the closed-form stress
    of the material at every step (the energy-momentum stress between the step's stretches)."""
    r = simulate(stretched_block(comm=COMM), pair="P2/P1", material=material, dt=0.1, T=1.0)
    d = r.discretisation
    xdof = d.W.tabulate_dof_coordinates()[:len(r.U.array) // 2]
    u = r.U.array.reshape(-1, 2)
    assert np.max(np.abs(u[:, 0] - G * 1.0 * xdof[:, 0]), initial=0.0) < 1e-10
    assert np.max(np.abs(u[:, 1]), initial=0.0) < 1e-10
    t = r.timeseries["t"]
    expected = [closed_form_reaction(material, 1 + G * t0, 1 + G * t1) for t0, t1 in zip(t[:-1], t[1:])]
    assert np.allclose(r.timeseries["reaction_right_x"][1:], expected, rtol=1e-9, atol=0.0)
    if material == "neo-hookean":       # not Hooke's law: at a stretch of 1.5 the stress is far from linear
        assert abs(expected[-1] - (LAM + 2 * MU) * 0.5 * G) > 0.1 * expected[-1]


# ------------------------------------------------------------------ contact: the pushed block
PUSHED = Path(__file__).resolve().parents[2] / "demos" / "pushed_block_problem.py"
#: the pushed block's Young's modulus, Poisson's ratio, width and height (its defaults, nu = 0.3)
E_B, NU_B, W_B, H_B = 1000.0, 0.3, 20.0, 10.0


def block_force(material, depth):
    """The force per mm of thickness of the block compressed by ``depth`` between frictionless plates
    (plane strain, free sides): the homogeneous state F = diag(l_x, l_y), l_y = 1 - depth/H, with
    S_xx(l_x) = 0, and the force -P_yy W = -l_y S_yy W; linear: E/(1 - nu^2) W depth/H."""
    mu, lam = E_B / (2 * (1 + NU_B)), E_B * NU_B / ((1 + NU_B) * (1 - 2 * NU_B))
    ly = 1.0 - depth / H_B
    if material == "linear":
        return E_B / (1 - NU_B ** 2) * W_B * depth / H_B
    if material == "svk":                   # S = lam tr(E) I + 2 mu E
        Ey = 0.5 * (ly ** 2 - 1.0)
        Ex = -lam * Ey / (lam + 2 * mu)
        return -ly * (lam * (Ex + Ey) + 2 * mu * Ey) * W_B
    S = lambda c, J: mu * (1 - 1 / c) + lam * np.log(J) / c       # noqa: E731  (neo-Hookean, C diagonal)
    lo, hi = 0.5, 2.0                       # S_xx(l_x) = 0 by bisection (S_xx increases with l_x)
    for _ in range(200):
        lo, hi = ((lo + hi) / 2, hi) if S(((lo + hi) / 2) ** 2, (lo + hi) / 2 * ly) < 0 else (lo, (lo + hi) / 2)
    lx = (lo + hi) / 2
    return -ly * S(ly * ly, lx * ly) * W_B


def pushed(material, depth, constrain=None):
    """The hold mean of the foundation's force and of the punch's (demos/pushed_block_problem.py: P1+/P0,
    a ramp slow against the block's vibrations, then held)."""
    ts = simulate(str(PUSHED), {"nu": NU_B, "depth": depth}, material=material, constrain=constrain).timeseries
    hold = ts["t"] > 5e-3 * (1 + 1e-9)
    return ts["contact_force"][hold].mean(), -ts["reaction_top_y"][hold].mean()


@pytest.mark.parametrize("constrain", ["vertices", "weighted"])
@pytest.mark.parametrize("material", ["svk", "neo-hookean"])
def test_pushed_block_is_the_finite_strain_closed_form(material, constrain):
    """Contact and prescribed motion at 10 % compression: the foundation's and the punch's forces are the
    material's closed form within 5e-4 (measured within 1.4e-4: the ramp's residual vibration), 14.5 %
    (svk) and 9.7 % (neo-Hookean) away from the linear model's, on opposite sides; the same with the weighted
    gap (fixed gap rows, solved by a gap-row Newton per tangent; exact on the flat foundation at any
    displacement; measured within 2.8e-5 neo-Hookean, 1.4e-4 svk)."""
    contact, punch = pushed(material, 1.0, constrain)
    F = block_force(material, 1.0)
    assert contact == pytest.approx(F, rel=5e-4) and punch == pytest.approx(F, rel=5e-4)
    assert abs(F / block_force("linear", 1.0) - 1) > 0.09


def test_initial_tangent_reaches_the_same_steps():
    """newton initial (the linear step matrix, the tangent at rest, factorised once for the run) on the block
    compressed by 10 %: the same forces as newton full to 1e-8 (measured 1.1e-9), no tangent factorised, more
    iterations. (On the spinning square, whose rotations leave T far from A, its iterations slow down and it
    takes a tangent: measured 1.1 per step.)"""
    runs = {}
    for newton in ("full", "initial"):
        ts = simulate(str(PUSHED), {"nu": NU_B, "depth": 1.0}, material="neo-hookean", newton=newton).timeseries
        runs[newton] = ts
    assert np.all(runs["initial"]["tangents"] == 0)
    assert runs["initial"]["nonlinear_its"][1:].mean() > runs["full"]["nonlinear_its"][1:].mean()
    F = block_force("neo-hookean", 1.0)
    assert np.max(np.abs(runs["initial"]["contact_force"] - runs["full"]["contact_force"])) < 1e-8 * F


def test_a_problem_files_psi_from_the_command_line(mpi_tmp_path):
    """The pushed block's file writes a neo-Hookean psi(C) by hand: ``run --problem-file ... --material problem``
    gives the built-in neo-Hookean's forces (to 1e-9), through the command line."""
    import json
    from sdm_dolfinx import cli
    out = mpi_tmp_path / "own"
    assert cli.main(["run", "--problem-file", str(PUSHED), "--nu", str(NU_B), "--depth", "1.0", "--material",
                     "problem", "--T", "0.006", "--out", str(out), "--quiet"]) == 0
    builtin = simulate(str(PUSHED), {"nu": NU_B, "depth": 1.0}, material="neo-hookean", T=0.006).timeseries
    if COMM.rank == 0:
        own = np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1)
        header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
        force = own[:, header.index("contact_force")]
        assert np.max(np.abs(force - builtin["contact_force"])) < 1e-9 * block_force("neo-hookean", 1.0)
        assert json.loads((out / "run.json").read_text())["material"] == "problem"


@pytest.mark.parametrize("material", ["svk", "neo-hookean"])
def test_small_strain_limit_of_the_patch_is_the_linear_model(material):
    """The patch test's stretch to strains e = 1e-3, 1e-2, 1e-1: the reaction of the last step (at the mean
    stretch 1 + 0.95 e) departs from the linear run's by c 0.95 e + O(e^2), c the closed form's first-order
    coefficient of P_xx((1 + e), 1) / ((lam + 2 mu) e) - 1: 3/2 for svk (P = l (lam + 2 mu) (l^2 - 1) / 2),
    -(mu + 3/2 lam) / (lam + 2 mu) = -1 for neo-Hookean (P = mu (l - 1/l) + lam ln(l) / l); asserted within 1 %
    at 1e-3 (measured 0.13 % and 0.02 %), and the fitted slope is 1 within 0.05."""
    c = 1.5 if material == "svk" else -(MU + 1.5 * LAM) / (LAM + 2 * MU)
    r = small_strain(material, COMM)
    assert r["departures"][0] / (0.95 * 1e-3) == pytest.approx(c, rel=0.01)
    assert r["slope"] == pytest.approx(1.0, abs=0.05)


def test_small_strain_limit_is_the_linear_model():
    """The same push at strains of 1e-3 and 1e-2: each material's force departs from the linear run's by
    O(strain) (fitted slope 1 within 0.05; measured -1.5 and +0.85 times the strain)."""
    for material in ("svk", "neo-hookean"):
        dev = []
        for depth in (0.01, 0.1):
            lin, fs = pushed("linear", depth)[0], pushed(material, depth)[0]
            dev.append(abs(fs / lin - 1))
        slope = np.log(dev[1] / dev[0]) / np.log(10.0)
        assert slope == pytest.approx(1.0, abs=0.05) and dev[0] < 2e-3, (material, dev)


# ------------------------------------------------------------------ a problem's own psi, refusals
def test_problem_psi_runs_like_the_builtin_law():
    """material problem with psi = Saint Venant-Kirchhoff written by hand (through the general discrete
    gradient) gives svk's steps to the Newton tolerance."""
    svk = simulate(spinning_square(), pair="P2/P1", material="svk", dt=DT, T=20 * DT).timeseries
    own = simulate(spinning_square(svk_psi), pair="P2/P1", material="problem", dt=DT, T=20 * DT).timeseries
    assert np.max(np.abs(own["energy"] - svk["energy"])) < 1e3 * RTOL * svk["energy"][0]
    assert np.max(np.abs(own["u_probe"] - svk["u_probe"])) < 1e-8


@pytest.mark.parametrize("material", ["svk", "neo-hookean"])
def test_an_unused_strain_energy_is_warned(material):
    """A problem that declares strain_energy run with another hyperelastic material: one line (rank 0) says its
    psi is not used; material problem runs it, and the linear model (the default) ignores it, without the
    warning."""
    for m, expected in ((material, True), ("problem", False), ("linear", False)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            simulate(spinning_square(svk_psi), pair="P2/P1", material=m, dt=DT, T=DT)
        said = [str(w.message) for w in caught if "declares strain_energy" in str(w.message)]
        assert len(said) == (1 if expected and COMM.rank == 0 else 0), said
        assert all("\n" not in w and f"material {m!r}" in w for w in said)


def test_refusals_are_one_line():
    """What the hyperelastic step cannot run is refused before anything is built or written."""
    wrong = lambda C: 2.0 * svk_psi(C)                                                  # noqa: E731
    cases = [(dict(problem=spinning_square(wrong), material="problem"), DiscretisationError, "tangent at rest"),
             (dict(problem=spinning_square(), material="problem"), DiscretisationError, "declares none"),
             (dict(problem="membrane", material="svk"), DiscretisationError, "vector displacement"),
             (dict(problem=spinning_square(), material="svk", scheme="central-difference"), DiscretisationError,
              "central-difference"),
             (dict(problem=spinning_square(), newton="modified"), RunInputError, "newton"),
             (dict(problem=spinning_square(), material="svk", linear="cg-gamg"), DiscretisationError, "cg-gamg"),
             (dict(problem=spinning_square(), material="rubber"), RunInputError, "rubber"),
             (dict(problem=spinning_square(lambda C: C), material="problem"), DiscretisationError,
              "must return a scalar"),
             (dict(problem=spinning_square(lambda C: 1 / 0), material="problem"), DiscretisationError,
              "strain_energy(C) failed"),
             (dict(problem="disc", params={"level": 1, "start": "equilibrium", "height": 0.0, "v0": 0.0},
                   material="neo-hookean", dt=1e-4, T=1e-4), DiscretisationError, "--start option"),
             (dict(problem="block", material="svk", dt=1e-4, T=1e-4), DiscretisationError, "equilibrium start")]
    for kw, error, words in cases:
        with pytest.raises(error) as e:
            simulate(**{"pair": "P2/P1", "dt": DT, "T": DT, **kw})
        assert words in str(e.value) and "\n" not in str(e.value), str(e.value)


@pytest.mark.filterwarnings("ignore::UserWarning")          # the P2 face's sink between vertices (measured)
def test_hard_steps_are_counted_in_the_time_series():
    """The disc (level 1, neo-Hookean) hitting the foundation at dt = 1e-3: its impact steps need the Newton
    steps halved (measured 4 halvings; without them this run diverged: finite_strain_step.ACCEPT), which the
    column ``backtracks`` shows; no iteration fell back to the step matrix at rest (``fallbacks`` 0); at
    dt = 5e-4 no step needs either."""
    hard = simulate("disc", {"level": 1}, material="neo-hookean", dt=1e-3, T=0.03).timeseries
    easy = simulate("disc", {"level": 1}, material="neo-hookean", dt=5e-4, T=0.03).timeseries
    assert hard["backtracks"].sum() >= 1 and hard["backtracks"][0] == 0
    assert easy["backtracks"].sum() == 0 and hard["fallbacks"].sum() == easy["fallbacks"].sum() == 0
    assert hard["n_active"].max() >= 1


@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize("friction", [{"constrain": "weighted"}, {"friction": "tresca",
                                                                  "friction_options": {"tresca_threshold": 1e-6}}],
                         ids=["weighted", "tresca"])
def test_hard_steps_backtrack_with_the_reaction_error(friction):
    """The same hard impact (dt = 1e-3) with gap rows or friction, whose error is measured against the last
    linear solve's reaction: a halved step's reaction is the mean of its two ends', so a halving can lower the
    error, and no step spends every halving (MAX_CUTS). Measured: 0 and 3 halvings in the run (with the last
    reaction kept for the halved iterate, every hard step spent all 10, and Tresca then failed at step 14)."""
    from sdm_dolfinx.run.finite_strain_step import MAX_CUTS
    ts = simulate("disc", {"level": 1}, material="neo-hookean", dt=1e-3, T=0.03, **friction).timeseries
    assert ts["n_active"].max() >= 1 and ts["backtracks"].max() < MAX_CUTS


# ------------------------------------------------------------------ run folder: restart, energy, picture
@pytest.mark.filterwarnings("ignore::UserWarning")          # the P2 face's sink between vertices (measured)
@pytest.mark.parametrize("friction", [{}, {"friction": "coulomb", "friction_options": {"mu": 0.3}}],
                         ids=["frictionless", "coulomb"])
def test_restart_and_recomputed_energy(mpi_tmp_path, friction):
    """A neo-Hookean disc through its impact (level 1, 60 steps; with Coulomb friction falling obliquely),
    stopped at step 17 and restarted from its checkpoint: the same time series as the uninterrupted run (bit
    for bit on one rank; 1e-9 on two, whose MUMPS factorisations are not bit-reproducible); its energy column
    recomputed from state.h5 by the energy command's code (psi of the material, not 1/2 a(u, u)) within
    1e-10."""
    import json
    from sdm_dolfinx.post.energy import recompute_energy
    kw = dict(pair="P2/P1", material="neo-hookean", dt=5e-4, T=0.03, write_every=2, **friction)
    params = {"level": 1, **({"vx0": 2000.0} if friction else {})}
    simulate("disc", params, out=mpi_tmp_path / "ref", **kw)
    with pytest.raises(Exception) as e:
        simulate("disc", params, out=mpi_tmp_path / "cut", checkpoint_every=5, on_step=lambda n, row: n == 17, **kw)
    assert type(e.value).__name__ == "Interrupted"
    r = simulate(out=mpi_tmp_path / "cut", checkpoint_every=5, restart=True)      # the run's own options
    assert r.timeseries["n_active"].max() >= 2                  # it did hit the foundation
    if COMM.rank == 0:
        a, b = (np.loadtxt(mpi_tmp_path / f / "timeseries.csv", delimiter=",", skiprows=1) for f in ("ref", "cut"))
        rtol = 0.0 if COMM.size == 1 else 1e-9
        assert a.shape == b.shape and np.allclose(a, b, rtol=rtol, atol=rtol * np.abs(a).max(axis=0))
        assert json.loads((mpi_tmp_path / "cut" / "run.json").read_text())["material"] == "neo-hookean"
    out = recompute_energy(mpi_tmp_path / "ref", COMM, write=False)
    assert out["max_rel_diff"] < 1e-10


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_restart_with_friction_on_the_weighted_gap(mpi_tmp_path):
    """The pushed block (ramp 3e-3 s) on the weighted gap with Coulomb friction (mu = 0.2), neo-Hookean, stopped
    at step 12 and restarted: the same physics to 1e-9 of each column's scale (measured 1e-12; the slip is read
    in the gap's rows from the restart's first step). The warm-start sets of the Newton iterations are not in the
    checkpoint, so the iteration counts may differ (measured: newton_its by a third)."""
    kw = dict(material="neo-hookean", constrain="weighted", friction="coulomb", friction_options={"mu": 0.2},
              dt=1e-4, T=3e-3)
    params = {"nu": NU_B, "depth": 1.0, "ramp": 3e-3}
    simulate(str(PUSHED), params, out=mpi_tmp_path / "ref", **kw)
    with pytest.raises(Exception) as e:
        simulate(str(PUSHED), params, out=mpi_tmp_path / "cut", checkpoint_every=5,
                 on_step=lambda n, row: n == 12, **kw)
    assert type(e.value).__name__ == "Interrupted"
    simulate(out=mpi_tmp_path / "cut", checkpoint_every=5, restart=True)
    if COMM.rank == 0:
        a, b = (np.loadtxt(mpi_tmp_path / f / "timeseries.csv", delimiter=",", skiprows=1) for f in ("ref", "cut"))
        header = (mpi_tmp_path / "ref" / "timeseries.csv").read_text().splitlines()[0].split(",")
        counts = {"newton_its", "nonlinear_its", "tangents", "backtracks", "fallbacks"}
        keep = [i for i, h in enumerate(header) if h not in counts]
        scale = np.abs(a[:, keep]).max(axis=0) + 1e-300
        assert a.shape == b.shape and np.all(np.abs(a[:, keep] - b[:, keep]).max(axis=0) <= 1e-9 * scale)
        assert np.abs(a[:, header.index("tangential_force")]).max() > 0     # friction acts


def test_picture_stress_is_the_cauchy_stress():
    """The von Mises stress of a picture (render) of a hyperelastic run is its Cauchy stress F S F^T / J:
    a uniaxial stretch of 1.3 in 3-D against the closed form (Saint Venant-Kirchhoff: S = diag(s_x, s_t,
    s_t), s_x = lam tr E + 2 mu E_xx, s_t = lam tr E; sigma = diag(1.3 s_x, s_t / 1.3, s_t / 1.3))."""
    from sdm_dolfinx.io.xdmf_reader import von_mises

    class Tet:                                       # one tetrahedron, as Series gives its cells
        points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])

        def linear_cells(self):
            return np.array([[0, 1, 2, 3]])
    u = np.zeros((4, 3))
    u[:, 0] = 0.3 * Tet.points[:, 0]
    Exx = 0.5 * (1.3 ** 2 - 1)
    sx, st = LAM * Exx + 2 * MU * Exx, LAM * Exx
    s = np.array([1.3 * sx, st / 1.3, st / 1.3])
    expected = np.sqrt(1.5 * np.sum((s - s.mean()) ** 2))
    assert von_mises(Tet(), u, LAM, MU, material="svk")[0] == pytest.approx(expected, rel=1e-12)
    hooke = np.array([LAM * 0.3 + 2 * MU * 0.3, LAM * 0.3, LAM * 0.3])
    assert von_mises(Tet(), u, LAM, MU)[0] == pytest.approx(np.sqrt(1.5 * np.sum((hooke - hooke.mean()) ** 2)))
