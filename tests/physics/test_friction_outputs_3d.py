"""3-D friction outputs are signed components, as in 2-D (they were magnitudes under the 2-D
names), and an energy that starts at 0 still has a scale: a body starting at rest.

The ball's oblique impact along the direction 135 degrees from x (towards -x, +y): the friction
on the ball opposes its slip, so the tangential force points along (+x, -y) and the probe
vertex's slip along (-x, +y)."""
import json

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli, simulate

COMM = MPI.COMM_WORLD
BALL = {"level": 1, "vt": 50.0, "vt_angle": 135.0}
RUN = dict(friction="coulomb", friction_options={"mu": 0.3}, T=1.2e-3, write_every=5)


def csv(folder):
    text = COMM.bcast((folder / "timeseries.csv").read_text() if COMM.rank == 0 else None, root=0)
    return np.genfromtxt(text.splitlines(), delimiter=",", names=True)


@pytest.fixture(scope="module")
def oblique(tmp_path_factory):
    out = COMM.bcast(str(tmp_path_factory.mktemp("ball")) if COMM.rank == 0 else None, root=0)
    from pathlib import Path
    out = Path(out) / "run"
    steps = []
    r = simulate("ball", BALL, out=out, on_step=lambda n, row: steps.append(None), **RUN)
    return out, r


def test_3d_time_series_has_the_signed_components(oblique):
    out, r = oblique
    ts = csv(out)
    names = ts.dtype.names
    assert "tangential_force" not in names and "slip_probe" not in names
    fx, fy = ts["tangential_force_x"], ts["tangential_force_y"]
    contact = ts["contact_force"] > 0
    assert contact.sum() > 5
    # opposing the slip (-x, +y): the force on the ball along (+x, -y), along the diagonal
    assert np.all(fx[contact] >= 0) and np.all(fy[contact] <= 0) and fx[contact].max() > 0
    ratio = -fy[contact] / fx[contact]                  # along the diagonal, within the vertices' scatter
    assert np.all((ratio > 0.5) & (ratio < 2.0)) and abs(ratio[-1] - 1.0) < 0.1, ratio
    # Coulomb: |sum lam_T| <= mu sum lam_N
    assert np.all(np.hypot(fx, fy) <= 0.3 * ts["contact_force"] * (1 + 1e-6) + 1e-15)
    sx, sy = ts["slip_probe_x"], ts["slip_probe_y"]
    moving = np.hypot(sx, sy) > 1e-12
    assert moving.any() and np.all(sx[moving] <= 0) and np.all(sy[moving] >= 0)
    assert r.timeseries["tangential_force_x"][-1] == fx[-1]


def test_3d_tangential_stress_is_a_vector(oblique):
    out, r = oblique
    if COMM.rank == 0:
        from sdm_dolfinx.io.xdmf_reader import read_xdmf
        s = read_xdmf(out)
        t = s.times[-1]
        tau = s.field("tangential_stress", t)
        status = s.field("contact_status", t).reshape(-1)
        assert tau.shape[1] == 3 and np.all(tau[:, 2] == 0.0)          # in the plane z = 0
        on, off = status > 0.25, np.abs(status) < 1e-9     # (mid-edge nodes: interpolated, round-off)
        scale = np.abs(tau).max()
        assert on.any() and scale > 0 and np.abs(tau[off]).max() <= 1e-12 * scale
        assert np.all(tau[on, 0] >= -1e-12 * scale) and np.all(tau[on, 1] <= 1e-12 * scale)
        # |tau| <= mu x the contact stress, vertex by vertex (to the step solver's tolerance, 1e-8)
        sigma = s.field("contact_stress", t).reshape(-1)
        assert np.all(np.hypot(tau[:, 0], tau[:, 1]) <= 0.3 * sigma * (1 + 1e-6) + 1e-12 * scale)
        assert '<Attribute Name="tangential_stress" AttributeType="Vector"' in (out / "solution.xdmf").read_text()


def test_2d_outputs_keep_their_names(mpi_tmp_path):
    r = simulate("block", {"nx": 4, "ny": 2}, out=mpi_tmp_path / "b", friction="coulomb",
                 friction_options={"mu": 0.3}, T=4e-4)
    assert "tangential_force" in r.timeseries and "slip_probe" in r.timeseries
    if COMM.rank == 0:
        assert '<Attribute Name="tangential_stress" AttributeType="Scalar"' in \
            (mpi_tmp_path / "b" / "solution.xdmf").read_text()


def test_energy_starting_at_zero_has_a_scale(mpi_tmp_path, capsys):
    """The block at rest on the floor with no velocity: J^0 = 0 exactly and the midpoint scheme
    keeps J at round-off while gravity turns potential into kinetic energy:
    max_energy_deviation() measures J against that energy (it was NaN), and the energy command
    prints finite numbers (it printed 'nan eps' and a relative difference of 1.7 against a
    largest |J| of 1e-17)."""
    out = mpi_tmp_path / "rest"
    r = simulate("block", {"start": "rest", "v0": 0.0}, out=out, T=2e-3)
    ts = r.timeseries
    assert ts["energy"][0] == 0.0 and ts["kinetic"].max() > 1e-4
    dev = r.max_energy_deviation()
    assert np.isfinite(dev) and dev < 1e-10
    capsys.readouterr()
    assert cli.main(["energy", str(out)]) == 0
    text = capsys.readouterr().out
    if COMM.rank == 0:
        assert "nan" not in text, text
        rel = float(text.split("max relative difference to timeseries.csv: ")[1].split()[0])
        assert rel < 1e-10, text
        info = json.loads((out / "run.json").read_text())
        assert info["status"] == "finished"


def test_energy_of_a_state_at_zero_is_zero():
    """Nothing moves, nothing loads it: every energy is 0, and so is the deviation (not NaN)."""
    r = simulate("block", {"start": "rest", "v0": 0.0, "gravity": 0.0}, T=4e-4)
    assert np.all(r.timeseries["energy"] == 0.0) and r.max_energy_deviation() == 0.0
