"""A moving obstacle (``Problem(moving_bound=True)``, ``lower_bound(x, t)``): closed forms.

* Galilean invariance (the bar of problems/bar.py, P2/P1, midpoint, NX = 20, dt = 2e-3, T = 0.8):
  a rigid wall u(0) >= -gap + V t moving at V onto the bar at rest equals, in the wall's frame, the bar
  flying at -V onto the fixed wall u(0) >= -gap. Discretely: write e for the uniform unit field
  of W^h (interpolated exactly) and let (U^n, Vbar^n) be the moving-wall run. Then
  U'^n = U^n - V t_n e, Vbar'^n = Vbar^n - V e satisfies the fixed-wall run's step exactly:
  A e = 0 (a free bar: a translation has no strain), so with alpha = 2/dt the step equation
  (alpha^2 M + A) X = L + M (alpha Vbar^n + alpha^2 U^n) + lam is solved by X' = X - V t_{n+1/2} e
  with the same lam, because alpha^2 t_n + alpha = alpha^2 t_{n+1/2} (M is only used linearly: the
  singular mass M = B^T C^-1 B moves e like any vector, whatever its kernel); and the constraint
  X'_0 >= -gap holds with equality exactly where X_0 >= -gap + V t_{n+1/2} does, which is the mean
  of the bounds at t_n and t_{n+1} the midpoint scheme imposes (a linear motion). The updates
  2 X - U^n and 2 alpha (X - U^n) - Vbar^n commute with the shift (2 t_{n+1/2} - t_n = t_{n+1};
  2 alpha dt / 2 - 1 = 1). So the contact force histories agree up to the step solver's tolerance
  and the round-off of the shifted right-hand sides: asserted within 1e-8 rho c V (measured
  2e-11), and u_probe differs by V t_n within 1e-8 (the same). Taking the bound at t_n instead
  (the wall half a step behind) shifts the whole contact and the forces differ by O(1): asserted
  > 0.05 rho c V, so the first assertion would catch a bound at the wrong time. The same holds on
  every step solver path that reads the bounds (the semi-smooth Newton with its Schur, cg-factor
  and LU strategies, SNES vinewtonrsls, the (U, V) block system of the consistent mass).
* The energy balance (the rod of problems/rod1d.py, P1/P1 and P2/P1, midpoint, NX = 20,
  dt = 5e-3, T = 3): the rod, fixed at x = 1, starts at rest in static equilibrium against the
  wall at s0 (u0 = s0 (1 - x), exact in P1 and P2: A U^0 = s0 e_0, U^0_0 = g(0)), and the wall
  moves as g(t) = s0 + a (1 - cos(omega t)) (s0 = 0.1, a = 0.04, omega = 1.5; it starts at rest,
  so that a massive contact vertex (P1/P1) is not hit either): the rod stays in contact (asserted:
  one active vertex every step). Then E^{n+1} - E^n = lam . (g(t_{n+1}) - g(t_n))
  exactly (:mod:`sdm_dolfinx.schemes.midpoint`; any mass M, the standard P1/P1 one too), so
  E - obstacle_work stays E^0 within 1e-10 E^0 (round-off; measured 4.4e-12 E^0 for both pairs, with
  obstacle_work reaching 1.39 E^0). With the bound taken at t_{n+1/2} instead of the mean (equal for
  a linear motion only; they differ by dt^2 a omega^2 cos(omega t) / 8), U^{n+1}_0 - g(t_{n+1}) no
  longer vanishes and E - W leaves E^0 (measured 1.2e-3 E^0 by T = 1): asserted > 1e-8 E^0, so the
  balance test would catch the wrong time. Backward Euler (dissipative) keeps
  the vertex on the obstacle at every t_{n+1} and E - W non-increasing.
* A floor rising under the block of problems/block.py, with and without Coulomb friction (the
  frictional step solver takes the step's bound too): see its test.
* What cannot take a moving bound refuses it in one line: the schemes that do not say when
  they impose it (newmark), the penalty contact; a fixed bound gets none of the new columns.
"""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.problems import bar, rod1d
from sdm_dolfinx.run import simulate
from sdm_dolfinx.schemes.midpoint import Midpoint

COMM = MPI.COMM_WORLD
V, GAP, DT = 1.0, 0.2, 2e-3
#: the runs' end: 0.6 after the impact at 0.2 (the default path), 0.1 after it (the other paths: time)
T_BAR, T_PATH = 0.8, 0.3


def _moving_wall_bar(speed=V, lag=0.0):
    """The bar at rest, the wall u(0) >= -gap + V (t - lag) moving onto it."""
    p = bar.problem(COMM, v=V, gap=GAP, NX=20)
    p.v0 = lambda x: np.zeros(x.shape[1])
    p.lower_bound = lambda x, t: np.full(x.shape[1], -GAP + speed * (t - lag))
    p.moving_bound = True
    return p


@pytest.fixture(scope="module")
def fixed_wall():
    p = bar.problem(COMM, v=V, gap=GAP, NX=20)
    return simulate(p, pair="P2/P1", scheme="midpoint", dt=DT, T=T_BAR).timeseries


#: every step solver path that reads the bounds: the semi-smooth Newton with each linear strategy,
#: SNES VI, and the (U, V) block system of the consistent mass
PATHS = [dict(), dict(linear="schur"), dict(linear="cg-factor"), dict(linear="lu"),
         dict(vi_solver="vinewtonrsls"), dict(mass="consistent")]


@pytest.mark.parametrize("path", PATHS, ids=lambda p: "-".join(map(str, p.values())) or "default")
def test_galilean_invariance_moving_wall_equals_moving_bar(path, fixed_wall):
    T = T_PATH if path else T_BAR
    s = simulate(_moving_wall_bar(), pair="P2/P1", scheme="midpoint", dt=DT, T=T, **path).timeseries
    if path:
        fixed_wall = simulate(bar.problem(COMM, v=V, gap=GAP, NX=20), pair="P2/P1", scheme="midpoint", dt=DT,
                              T=T, **path).timeseries
    f, f_ref = s["contact_force"], fixed_wall["contact_force"]
    assert f_ref.max() > 0.5                                     # the contact happened (rho c V = 1)
    assert np.max(np.abs(f - f_ref)) <= 1e-8
    assert np.max(np.abs(s["u_probe"] - s["t"] * V - fixed_wall["u_probe"])) <= 1e-8
    # the obstacle's position (the bound at the probe's vertex x = 0) and its work
    assert np.allclose(s["obstacle_probe"], -GAP + V * s["t"], rtol=0, atol=1e-14)
    work = np.concatenate([[0.0], np.cumsum(f[1:] * V * DT)])
    assert np.allclose(s["obstacle_work"], work, rtol=0, atol=1e-12)


def test_galilean_invariance_fails_with_the_bound_at_the_wrong_time(fixed_wall, monkeypatch):
    monkeypatch.setattr(Midpoint, "bound_weight", 0.0)           # the bound at t_n: half a step behind
    s = simulate(_moving_wall_bar(), pair="P2/P1", scheme="midpoint", dt=DT, T=T_BAR).timeseries
    assert np.max(np.abs(s["contact_force"] - fixed_wall["contact_force"])) > 0.05


S0, A, OMEGA = 0.1, 0.04, 1.5


def _pressed_rod(scheme="midpoint", pair="P1/P1", T=3.0, dt=5e-3):
    p = rod1d.problem(COMM, NX=20)
    p.u0 = lambda x: S0 * (1.0 - x[0])
    p.lower_bound = lambda x, t: np.full(x.shape[1], S0 + A * (1.0 - np.cos(OMEGA * t)))
    p.moving_bound = True
    return simulate(p, pair=pair, scheme=scheme, dt=dt, T=T).timeseries


@pytest.mark.parametrize("pair", ["P1/P1", "P2/P1"])
def test_energy_minus_obstacle_work_is_conserved_in_sustained_contact(pair):
    s = _pressed_rod(pair=pair)
    assert np.all(s["n_active"][1:] == 1)                        # sustained contact: the premise
    E0 = 0.5 * S0 ** 2                                           # 1/2 U^T A U of the static start
    assert abs(s["energy"][0] - E0) <= 1e-12 * E0
    balance = s["energy"] - s["obstacle_work"]
    assert np.max(np.abs(balance - E0)) <= 1e-10 * E0
    assert np.max(np.abs(s["obstacle_work"])) > 0.1 * E0         # the wall did work
    assert np.allclose(s["obstacle_probe"], S0 + A * (1.0 - np.cos(OMEGA * s["t"])), rtol=0, atol=1e-15)
    assert np.max(np.abs(s["u_probe"] - s["obstacle_probe"])) <= 1e-12    # on the wall at every t_n


def test_energy_balance_fails_with_the_bound_at_the_half_step(monkeypatch):
    # g(t_{n+1/2}) instead of the mean (g(t_n) + g(t_{n+1})) / 2 (step_bound is called once per step, in order)
    steps = iter(range(10 ** 6))

    def at_half_step(self, g0, g1):
        t_half = (next(steps) + 0.5) * 5e-3
        return np.full_like(g0, S0 + A * (1.0 - np.cos(OMEGA * t_half)))
    monkeypatch.setattr(Midpoint, "step_bound", at_half_step)
    s = _pressed_rod(T=1.0)
    E0 = 0.5 * S0 ** 2
    assert np.max(np.abs(s["energy"] - s["obstacle_work"] - E0)) > 1e-8 * E0


def test_backward_euler_keeps_the_vertex_on_the_wall_and_dissipates():
    s = _pressed_rod(scheme="backward-euler", T=1.0)
    assert np.all(s["n_active"][1:] == 1)
    assert np.max(np.abs(s["u_probe"] - s["obstacle_probe"])) <= 1e-12
    balance = s["energy"] - s["obstacle_work"]
    assert np.all(np.diff(balance) <= 1e-12 * balance[0])


@pytest.mark.parametrize("options, words", [
    ({"scheme": "newmark"}, "which scheme .* does not take"),
    ({"contact": "penalty"}, "contact 'penalty'"),
    ({"contact": "nitsche"}, "contact 'nitsche'"),
    ({"scheme": "central-difference", "mass": "redistributed", "pair": "P1/P1"}, "which scheme .* does not take"),
])
def test_a_moving_bound_is_refused_where_it_cannot_be_taken(options, words):
    with pytest.raises(SdmError, match=words):
        simulate(_moving_wall_bar(), **{"pair": "P2/P1", "dt": DT, "T": 10 * DT, **options})


def test_a_fixed_bound_has_no_obstacle_columns(fixed_wall):
    assert "obstacle_work" not in fixed_wall and "obstacle_probe" not in fixed_wall


WALL_FILE = '''"""A bar at rest, a wall moving onto it at the speed V."""
import numpy as np
from sdm_dolfinx.problems import Param, ProblemSpec, bar


def build(comm, V, NX):
    p = bar.SPEC.build(comm, L=1.0, E=1.0, rho=1.0, v=1.0, gap=0.2, NX=NX)
    p.name, p.v0 = "wall", (lambda x: np.zeros(x.shape[1]))
    p.lower_bound = lambda x, t: np.full(x.shape[1], -0.2 + V * t)
    p.moving_bound = True
    return p


PROBLEM = ProblemSpec(name="wall", build=build, doc=__doc__,
                      params=(Param("V", 1.0, "the wall's speed"), Param("NX", 20, "cells", type=int, low=1)),
                      defaults={"pair": "P2/P1", "dt": 2e-3, "T": 0.4})
'''


def test_a_problem_file_declares_a_moving_wall_and_render_places_it(mpi_tmp_path, clean_registry):
    import json
    from sdm_dolfinx.post.render_obstacle import declared_obstacle
    path = mpi_tmp_path / "wall.py"
    if COMM.rank == 0:
        path.write_text(WALL_FILE)
    COMM.Barrier()
    r = simulate(str(path), {"V": 1.0}, out=mpi_tmp_path / "run")
    s = r.timeseries
    assert s["obstacle_probe"][-1] == pytest.approx(-0.2 + 0.4, abs=1e-14)
    assert s["contact_force"].max() > 0.5 and s["obstacle_work"][-1] > 0
    if COMM.rank == 0:
        run = json.loads((mpi_tmp_path / "run" / "run.json").read_text())
        assert run["problem"]["bound"].startswith("moving")
        header = (mpi_tmp_path / "run" / "timeseries.csv").read_text().splitlines()[0]
        assert "obstacle_work" in header and "obstacle_probe" in header
        drawn = declared_obstacle(run, 0.3)          # a scalar u: the points are (x, y, bound)
        assert drawn["points"][0][2] == pytest.approx(-0.2 + 0.3, abs=1e-14) and "it moves" in drawn["note"]
        assert "unknown" in declared_obstacle(run, None)        # an animation: not drawn, said why
    COMM.Barrier()
    # a restart extends it as if run in one go (the bound of each step is evaluated afresh)
    simulate(str(path), {"V": 1.0}, out=mpi_tmp_path / "cut", T=0.2)
    e = simulate(out=mpi_tmp_path / "cut", restart=True, T=0.4).timeseries
    for column in ("contact_force", "obstacle_work", "obstacle_probe", "energy"):
        assert np.allclose(e[column], s[column], rtol=0, atol=1e-12), column


FLOOR_FILE = """
import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh
from sdm_dolfinx.problems import Param, Problem, ProblemSpec


def build(comm, lift):
    msh = dmesh.create_rectangle(comm, [np.zeros(2), np.array([2.0, 1.0])], [4, 2], dmesh.CellType.triangle)
    eps = lambda u: ufl.sym(ufl.grad(u))
    bottom = lambda x: np.isclose(x[1], 0.0)
    zero = lambda x: np.zeros((2, x.shape[1]))
    return Problem(name="floor", mesh=msh, shape=(2,), a=lambda u, w: ufl.inner(eps(u), eps(w)) * ufl.dx,
                   l=lambda w: ufl.inner(fem.Constant(msh, np.zeros(2)), w) * ufl.dx, u0=zero, v0=zero,
                   constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom),
                   lower_bound=lambda x, t: lift * t - x[1], moving_bound=True, constraint_component=1,
                   constraint_measure=lambda q: q * ufl.ds, probe=(1.0, 0.0))


PROBLEM = ProblemSpec(name="floor", build=build, params=(Param("lift", 0.1, "rise per unit time"),),
                      defaults={"pair": "P1+/P0", "dt": 0.01, "T": 0.3})
"""


def test_render_draws_a_moving_obstacle_where_it_is_at_each_picture_time(mpi_tmp_path, clean_registry):
    """A floor rising as y = 0.1 t under a block: a Series asked for the obstacle at two times gives
    it at each, and the render command draws it at the picture's time without a warning (a new
    user's render --png --time said "not drawn": the command asked once for an animation's
    obstacle, which was then kept for the picture)."""
    import warnings
    from sdm_dolfinx import cli
    from sdm_dolfinx.post import render
    path = mpi_tmp_path / "floor.py"
    if COMM.rank == 0:
        path.write_text(FLOOR_FILE)
    COMM.Barrier()
    out = mpi_tmp_path / "run"
    simulate(str(path), out=out)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert cli.main(["render", str(out), "--png", str(mpi_tmp_path / "floor.png"), "--time", "0.2"]) == 0
    if COMM.rank == 0:
        assert not [w for w in caught if "not drawn" in str(w.message)], [str(w.message) for w in caught]
        assert (mpi_tmp_path / "floor.png").stat().st_size > 10_000
        series = render.read_xdmf(out)
        for t in (0.1, 0.2, 0.1):
            assert render.obstacle_of(series, t)["flat"] == pytest.approx(0.1 * t, abs=1e-12)
    COMM.Barrier()


RISE, OMEGA_FLOOR = 0.01, 2 * np.pi / 0.02


@pytest.mark.parametrize("friction", [None, "coulomb"])
def test_a_rising_floor_lifts_the_block_with_and_without_friction(friction):
    """The block of problems/block.py (P2/P1, midpoint, equilibrium start, 10 x 5, dt = 1e-4 s) on a
    floor rising as y = s(t) = a (1 - cos(omega t)) (a = 0.01 mm, omega = 2 pi / 20 ms: its
    acceleration at most a omega^2 = 0.1 g, so the block stays on it): the frictional step solver
    takes the bound of each step too. The probe's bottom vertex is on the floor at every t_n (u_y =
    s(t_n) within 1e-12 a); frictionless, every bottom vertex stays in contact and E - obstacle_work
    = E^0 within 1e-9 E^0 (measured 1.1e-10: the start is the equilibrium computed to its solver's
    tolerance, not exactly U^0 = g(0))."""
    from sdm_dolfinx.problems import block
    p = block.problem(COMM)
    p.lower_bound = lambda x, t: RISE * (1.0 - np.cos(OMEGA_FLOOR * t)) - x[1]
    p.moving_bound = True
    kw = dict(friction="coulomb", friction_options={"mu": 0.3}) if friction else {}
    s = simulate(p, dt=1e-4, T=0.01, **kw).timeseries
    floor = RISE * (1.0 - np.cos(OMEGA_FLOOR * s["t"]))
    assert np.allclose(s["obstacle_probe"], floor, rtol=0, atol=1e-15)
    assert np.max(np.abs(s["u_probe"] - floor)) <= 1e-12 * RISE
    assert s["obstacle_work"][-1] > 0.01 * abs(s["energy"][0])
    if friction is None:
        assert np.all(s["n_active"][1:] == s["n_active"][1])
        balance = s["energy"] - s["obstacle_work"]
        assert np.max(np.abs(balance - balance[0])) <= 1e-9 * abs(balance[0])


def test_the_command_line_runs_a_moving_wall_and_refuses_a_scheme_that_cannot(mpi_tmp_path, capsys, clean_registry):
    """The problem file above from the command line and a TOML configuration (exit 0), the energy
    command on its folder; newmark is refused in one line, exit 2, nothing written."""
    from sdm_dolfinx import cli
    path = mpi_tmp_path / "wall.py"
    if COMM.rank == 0:
        path.write_text(WALL_FILE)
        (mpi_tmp_path / "wall.toml").write_text(f'problem-file = "{path}"\nT = 0.25\nV = 0.5\n')
    COMM.Barrier()
    out = mpi_tmp_path / "cli"
    assert cli.main(["run", "--problem-file", str(path), "--T", "0.25", "--quiet", "--out", str(out)]) == 0
    assert cli.main(["run", "--config", str(mpi_tmp_path / "wall.toml"), "--quiet", "--out",
                     str(mpi_tmp_path / "toml")]) == 0
    assert cli.main(["energy", str(out)]) == 0
    capsys.readouterr()
    bad = mpi_tmp_path / "bad"
    assert cli.main(["run", "--problem-file", str(path), "--scheme", "newmark", "--out", str(bad)]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert "moving bound" in err and len(err.strip().splitlines()) == 1, err
        assert not bad.exists()


@pytest.mark.parametrize("moving, bound, words", [
    (True, lambda x: np.zeros(x.shape[1]), "moving_bound=True: lower_bound takes"),
    (False, lambda x, t: np.zeros(x.shape[1]), "needs Problem\\(moving_bound=True\\)"),
])
def test_a_bound_of_the_wrong_signature_is_refused_in_one_line(moving, bound, words):
    p = bar.problem(COMM, NX=4)
    p.lower_bound, p.moving_bound = bound, moving
    with pytest.raises(SdmError, match=words):
        simulate(p, dt=DT, T=2 * DT)
