"""The closed forms of the 1-D benchmarks (problems/rod1d.py, problems/bar.py) satisfy their
problem, checked on the formulas themselves (no finite elements):

* the wave equation rho u_tt = E u_xx, by central differences of the closed form away from
  the characteristics (where u is smooth), and the velocity and strain the closed form gives
  are u's own time and space derivatives (central differences, exact for the piecewise-linear
  u up to round-off);
* the initial and boundary conditions (u(1) = 0 for the rod; E u_x(L) = 0 for the bar);
* the Signorini conditions at the contact point: gap >= 0, contact stress >= 0, their product
  0, and the contact stress is -E u_x there; the listed contact intervals are where the stress
  is positive;
* the energy 1/2 int (rho v^2 + E u_x^2) dx, by quadrature of the closed form, is constant to
  1e-10 (and equals its initial value); the momentum balance d/dt int rho v dx = contact
  stress (+ the fixed end's reaction E u_x(1) for the rod), integrated in time.

The rod's closed form also equals GetFEM's ``uExact`` of demo_dynamic_contact_1D.py (checked
by hand at 20000 random (x, t) and on a grid through the characteristics: identical), which
this test does not import.
"""
import numpy as np
import pytest

from sdm_dolfinx.problems import bar, rod1d
from sdm_dolfinx.problems.bar import BarExact, PlaneBarExact
from sdm_dolfinx.problems.rod1d import RodExact

#: a bar with c != 1, rho != 1, so that a misplaced c or rho shows
BAR = dict(L=2.0, E=3.0, rho=0.5, v=0.7, gap=0.3)
EPS = 1e-4           # the finite-difference step


def _rod():
    return RodExact(horizon=12.0), 1.0, 1.0, 1.0      # (exact, L, E, rho)


def _bar():
    return BarExact(**BAR, horizon=10.0), BAR["L"], BAR["E"], BAR["rho"]


CASES = {"rod1d": _rod, "bar": _bar}


def _far_from_characteristics(ex, L, x, t, margin):
    """Points whose distance (in x) to every characteristic through a kink of u exceeds
    ``margin``: the rod's kinks lie on x -+ t in Z, the bar's on x = c (t - t0) and
    x = 2L - c (t - t0)."""
    if isinstance(ex, RodExact):
        d = np.minimum(np.abs((x - t) - np.round(x - t)), np.abs((x + t) - np.round(x + t)))
    else:
        cs = ex.c * (t - ex.t0)
        d = np.minimum(np.abs(x - cs), np.abs(x - (2.0 * L - cs)))
    return d > margin


def _samples(L, T, n=4000, seed=1):
    rng = np.random.default_rng(seed)
    return L * rng.uniform(0.01, 0.99, n), rng.uniform(0.0, T, n)


@pytest.mark.parametrize("name", CASES)
def test_wave_equation_and_derivatives(name):
    ex, L, E, rho = CASES[name]()
    x, t = _samples(L, 12.0 if name == "rod1d" else 6.0)
    c = np.sqrt(E / rho)
    keep = _far_from_characteristics(ex, L, x, t, 4 * c * EPS) & (t > 2 * EPS)
    x, t = x[keep], t[keep]
    assert keep.sum() > 2500
    X = np.vstack([x, 0 * x, 0 * x])
    u = lambda dx, dt: ex.displacement(X + np.array([[dx], [0], [0]]), t + dt)        # noqa: E731
    u_tt = (u(0, EPS) - 2 * u(0, 0) + u(0, -EPS)) / EPS ** 2
    u_xx = (u(EPS, 0) - 2 * u(0, 0) + u(-EPS, 0)) / EPS ** 2
    # second differences of values of size ~1 lose ~1e-16 / EPS^2 = 1e-8 to round-off: u is
    # piecewise linear, so both vanish up to that, while a quadratic term a x^2 would give 2a
    assert np.abs(rho * u_tt - E * u_xx).max() < 1e-6
    assert np.abs(u_tt).max() < 1e-6 and np.abs(u_xx).max() < 1e-6
    np.testing.assert_allclose((u(0, EPS) - u(0, -EPS)) / (2 * EPS), ex.velocity(X, t), atol=1e-10)
    np.testing.assert_allclose((u(EPS, 0) - u(-EPS, 0)) / (2 * EPS), ex.strain(X, t), atol=1e-10)


@pytest.mark.parametrize("name", CASES)
def test_u_is_continuous(name):
    """u is continuous across the characteristics (a closed form with a wrong zone jumps)."""
    ex, L, _, _ = CASES[name]()
    x, t = _samples(L, 12.0 if name == "rod1d" else 6.0, seed=2)
    X = np.vstack([x, 0 * x, 0 * x])
    h = 1e-7
    for dX, dt in ((np.array([[h], [0], [0]]), 0.0), (0.0, h)):
        jump = np.abs(ex.displacement(X + dX, t + dt) - ex.displacement(X, t))
        assert jump.max() < 2 * h * max(1.0, ex.velocity(X, t).max(), np.sqrt(ex.energy))


def test_rod_initial_and_boundary_conditions():
    ex = RodExact()
    x = np.linspace(0.0, 1.0, 101)
    X = np.vstack([x, 0 * x, 0 * x])
    np.testing.assert_allclose(ex.displacement(X, 0.0), 0.5 - 0.5 * x, atol=1e-15)
    np.testing.assert_allclose(ex.velocity(X, 1e-12 * 0), np.where(x > 0, 0.0, -0.5), atol=1e-15)
    t = np.linspace(0.0, 12.0, 2401)
    np.testing.assert_allclose(rod1d.displacement(np.ones_like(t), t), 0.0, atol=1e-15)     # u(1) = 0
    # periodic of period 3
    for s in (0.3, 1.7, 2.4):
        np.testing.assert_allclose(ex.displacement(X, s + 3.0), ex.displacement(X, s), atol=1e-14)


def test_bar_initial_and_boundary_conditions():
    ex = BarExact(**BAR)
    x = np.linspace(0.0, BAR["L"], 101)
    X = np.vstack([x, 0 * x, 0 * x])
    np.testing.assert_allclose(ex.displacement(X, 0.0), 0.0, atol=1e-15)
    np.testing.assert_allclose(ex.velocity(X, 0.0), -BAR["v"], atol=1e-15)
    t = np.linspace(0.0, 10.0, 2001)
    end = np.vstack([np.full_like(t, BAR["L"]), 0 * t, 0 * t])
    for s in t:                                                  # the free end: E u_x(L) = 0
        assert ex.strain(end[:, :1], s)[0] == 0.0
    after = t > ex.t1
    np.testing.assert_allclose(bar.velocity(0.5 * BAR["L"], t[after], ex.L, ex.c, ex.v, ex.gap), BAR["v"])


@pytest.mark.parametrize("name", CASES)
def test_signorini_conditions(name):
    ex, L, E, _ = CASES[name]()
    t = np.linspace(0.0, ex.horizon, 20001)
    zero = np.zeros(len(t))
    bound = 0.0 if name == "rod1d" else -BAR["gap"]
    gap = ex.displacement(np.vstack([zero, zero, zero]), t) - bound
    lam = ex.contact_stress(t)
    assert gap.min() >= -1e-15 and lam.min() >= 0.0
    assert np.abs(gap * lam).max() < 1e-15
    np.testing.assert_allclose(lam, -E * ex.strain(np.vstack([zero, zero, zero]), t), atol=0)
    inside = np.zeros(len(t), dtype=bool)
    for a, b in ex.contact_intervals:
        inside |= (t >= a) & (t < b)
    np.testing.assert_array_equal(lam > 0, inside)
    assert len(ex.contact_intervals) == (4 if name == "rod1d" else 1)
    stress = 0.5 if name == "rod1d" else BAR["rho"] * np.sqrt(BAR["E"] / BAR["rho"]) * BAR["v"]
    np.testing.assert_allclose(lam[inside], stress, rtol=1e-15)


def _gauss(L, n=2000, order=3):
    """Composite Gauss-Legendre points and weights on [0, L]."""
    g, w = np.polynomial.legendre.leggauss(order)
    edges = np.linspace(0.0, L, n + 1)
    a, b = edges[:-1, None], edges[1:, None]
    return (0.5 * (a + b) + 0.5 * (b - a) * g).ravel(), (0.5 * (b - a) * w).ravel()


@pytest.mark.parametrize("name", CASES)
def test_energy_constant_and_momentum_balance(name):
    ex, L, E, rho = CASES[name]()
    x, w = _gauss(L)
    X = np.vstack([x, 0 * x, 0 * x])
    times = np.linspace(0.0, ex.horizon, 241)
    energy = np.array([0.5 * np.sum(w * (rho * ex.velocity(X, s) ** 2 + E * ex.strain(X, s) ** 2)) for s in times])
    assert np.ptp(energy) <= 1e-10 * energy[0]
    assert abs(energy[0] - ex.energy) <= 1e-12 * ex.energy
    # momentum balance: int rho v dx changes by the time integral of the boundary forces
    momentum = np.array([np.sum(w * rho * ex.velocity(X, s)) for s in times])
    tt, wt = _gauss(ex.horizon, n=24000, order=1)                 # midpoint rule in time
    force = ex.contact_stress(tt)
    if name == "rod1d":                                       # the fixed end's reaction E u_x(1, t)
        force = force + E * rod1d.strain(np.ones_like(tt), tt)
    impulse = np.concatenate([[0.0], np.cumsum([np.sum(wt * force * ((tt >= a) & (tt < b)))
                                                  for a, b in zip(times[:-1], times[1:])])])
    np.testing.assert_allclose(momentum - momentum[0], impulse, atol=2e-3 * max(1.0, np.abs(momentum).max()))


def test_bar_one_impact_numbers():
    """Contact duration 2L/c, stress rho c v, release at +v, no second impact."""
    ex = BarExact(**BAR, horizon=50.0)
    c = np.sqrt(BAR["E"] / BAR["rho"])
    assert ex.contact_intervals == [(BAR["gap"] / BAR["v"], BAR["gap"] / BAR["v"] + 2 * BAR["L"] / c)]
    assert ex.stress == pytest.approx(BAR["rho"] * c * BAR["v"], rel=1e-15)


def test_plane_bar_is_the_1d_solution():
    """The plane bar of demos/bar_problem.py: u = (u_1D(x - d, t), 0), the wall x = 0."""
    p = dict(L=100.0, E=2e5, rho=7.85e-9, v=1000.0, gap=0.5)
    ex, one = PlaneBarExact(**p, H=10.0), BarExact(**p)
    rng = np.random.default_rng(3)
    x = np.vstack([p["gap"] + p["L"] * rng.random(500), 10.0 * rng.random(500), np.zeros(500)])
    for t in (0.0, 1e-4, 3e-4, 1e-3):
        u = ex.displacement(x, t)
        assert u.shape == (2, 500) and not u[1].any()
        np.testing.assert_allclose(u[0], one.displacement(x[0] - p["gap"], t), rtol=0, atol=0)
        g = ex.strain(x, t)
        assert g.shape == (2, 2, 500) and not g[1].any() and not g[0, 1].any()
    # the end face reaches the wall x = 0: x + u_x = 0 there during the contact
    face = np.array([[p["gap"]], [5.0], [0.0]])
    mid = 0.5 * (ex.t0 + ex.t1)
    assert abs(p["gap"] + ex.displacement(face, mid)[0, 0]) < 1e-12 * p["L"]
