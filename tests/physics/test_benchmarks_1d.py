"""Runs of the 1-D benchmarks against their closed forms (problems/rod1d.py, problems/bar.py),
and their XDMF output on interval meshes.

* rod1d, P1/P1 (standard Galerkin, exact contact), midpoint, one period T = 3 (flight,
  contact, flight), NX = 40, 80, 160 with dt = h/10: the L2-in-time error of the displacement
  of the contact point decreases at every level with the fitted rate >= 0.8 (measured:
  2.58e-2, 8.53e-3, 4.16e-3, rate 1.32; NX = 320, 640 go on at about 1). Measured alongside,
  not asserted: at NX = 10, 20, 40 the errors are not monotone (3.2e-2, 2.1e-2, 2.6e-2), and
  with dt = h/4 or h/2 they stall near 7e-3 from NX = 80 on; the standard mass's energy grows
  by a factor 3 to 5 at the impact at every level (the paper's point), while u(0, t) converges.
* bar, P2/P1 (the singular dynamic method, well-posed), midpoint, dt = h/25, T = 3.2: the
  impact at t0 = 0.2 to within a step, the contact duration (last minus first step with a
  positive multiplier) within 2 % of 2L/c at NX = 80 (measured 1.9815 = 2L/c - 0.93 %; NX =
  40: -1.6 %, NX = 160: -0.55 %: the release comes early by the dispersion of the discrete
  wave front) and closer at NX = 80 than at NX = 40; the impulse of the contact within 2 % of
  2 rho v L, the exact momentum change (measured -0.85 %).
* solution.xdmf of an interval mesh: P1 as dolfinx writes it (``PolyLine``), P2 with its
  mid-edge nodes (``Edge_3``), points as ``XY``; in the bar's free flight before the impact
  the written displacement is -v t and the velocity -v at every node (the midpoint scheme is
  exact on a rigid motion); the same checks hold on 2 ranks.
"""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx.problems import bar, rod1d
from sdm_dolfinx.run import simulate

COMM = MPI.COMM_WORLD


def _contact_point_error(NX, pair="P1/P1", ratio=0.1, T=3.0):
    """L2-in-time error (root mean square over (0, T]) of u(0, t), dt = ratio h."""
    p = rod1d.problem(COMM, NX=NX)
    ex = rod1d.SPEC.exact(p)
    dt = ratio / NX
    r = simulate(p, pair=pair, scheme="midpoint", dt=dt, T=T)
    t, u = r.timeseries["t"], r.timeseries["u_probe"]
    e = u - ex.displacement(np.zeros((3, len(t))), t)
    return float(np.sqrt(np.sum(e[1:] ** 2) * dt / T))


def test_rod1d_p1p1_midpoint_converges_at_the_contact_point():
    NX = np.array([40, 80, 160])
    errors = np.array([_contact_point_error(n) for n in NX])
    rate = -np.polyfit(np.log(NX), np.log(errors), 1)[0]
    assert np.all(np.diff(errors) < 0), errors
    assert rate >= 0.8, (errors, rate)
    assert errors[-1] < 1e-2


def _bar_run(NX):
    p = bar.problem(COMM, NX=NX)
    dt = 0.04 / NX                                     # h / 25 with the default L = 1
    r = simulate(p, pair="P2/P1", scheme="midpoint", dt=dt, T=3.2)
    lam = r.timeseries["contact_force"][1:]           # the multiplier of step n -> n + 1
    on = np.flatnonzero(lam > 0)
    return p, dt, on[0] * dt, (on[-1] + 1) * dt, float(lam.sum() * dt)


def test_bar_contact_duration_and_impulse():
    durations = {}
    for NX in (40, 80):
        p, dt, first, last, impulse = _bar_run(NX)
        ex = bar.SPEC.exact(p)
        assert abs(first - ex.t0) <= dt * (1 + 1e-9)
        durations[NX] = last - first
    exact = 2.0 * ex.L / ex.c
    assert abs(durations[80] - exact) <= 0.02 * exact, durations
    assert abs(durations[80] - exact) < abs(durations[40] - exact), durations
    assert abs(impulse - 2.0 * ex.rho * ex.v * ex.L) <= 0.02 * 2.0 * ex.rho * ex.v * ex.L


@pytest.mark.mpi
@pytest.mark.parametrize("pair, topology, nodes", [("P1/P1", "PolyLine", 2), ("P2/P1", "Edge_3", 3)])
def test_interval_xdmf(mpi_tmp_path, pair, topology, nodes):
    NX, dt = 10, 0.01
    out = mpi_tmp_path / pair.replace("/", "-")
    p = bar.problem(COMM, NX=NX)
    simulate(p, pair=pair, scheme="midpoint", dt=dt, T=0.1, out=out, write_every=5)   # before the impact
    if COMM.rank != 0:
        return
    from sdm_dolfinx.io.xdmf_reader import read_xdmf
    text = (out / "solution.xdmf").read_text()
    assert f'TopologyType="{topology}"' in text and 'GeometryType="XY"' in text
    s = read_xdmf(out)
    assert s.cells.shape == (NX, nodes)
    assert len(s.points) == NX + 1 + (NX if nodes == 3 else 0)
    assert not s.points[:, 1:].any()
    x = s.points[:, 0]
    np.testing.assert_allclose(np.sort(x[s.cells[:, :2]].ravel()), np.repeat(np.linspace(0, 1, NX + 1), 2)[1:-1],
                               atol=1e-15)
    if nodes == 3:                                     # VTK's quadratic edge: the midpoint last
        np.testing.assert_allclose(x[s.cells[:, 2]], x[s.cells[:, :2]].mean(axis=1), atol=1e-15)
    v = p.parameters["v"]
    assert np.allclose(s.times, [0.0, 0.05, 0.1])
    for t in s.times:
        np.testing.assert_allclose(s.field("displacement", t).ravel(), -v * t, atol=1e-13)
        np.testing.assert_allclose(s.field("velocity", t).ravel(), -v, atol=1e-13)
