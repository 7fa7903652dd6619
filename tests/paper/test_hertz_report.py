"""The report's section "3-D: the ball against Hertz": its reference values are Hertz's closed
forms, its table has the expected columns, a rerun computes nothing, and its verdict follows the issue's
5 % criterion on the finest level."""
import gc
import math
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx.report import hertz_entry as hertz_report
from sdm_dolfinx.study.entry import Verdict
from sdm_dolfinx.problems import ball

COMM = MPI.COMM_WORLD
#: one cheap run: level 1 at a coarse dt (10-20 s with the set-up: the tests using it are marked slow)
RUN = ((1, 8e-5),)


@pytest.fixture(scope="module")
def study():
    """The section's study on RUN in a temporary folder (collective), run twice: (rows, rows again,
    number computed by the second call, folder)."""
    path = Path(COMM.bcast(tempfile.mkdtemp(prefix="sdm_hertz_") if COMM.rank == 0 else None, root=0))
    rows, computed = hertz_report.run_study(RUN, path, COMM, say=lambda s: None)
    assert computed == 1
    again, computed_again = hertz_report.run_study(RUN, path, COMM, say=lambda s: None)
    yield rows, again, computed_again, path
    gc.collect()
    COMM.Barrier()
    if COMM.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


@pytest.mark.slow
def test_reference_is_hertz_closed_form(study):
    """The table's Hertz values: delta_max from the energy, F = 4/3 E* sqrt(R) delta^(3/2), t_c =
    (4/5) B(2/5, 1/2) delta_max / v, a = sqrt(R delta_max), p0 = 3 F / (2 pi a^2), at the defaults."""
    from scipy.special import beta
    ref = study[0][0]["hertz"]
    R, E, nu, rho, v = 20.0, 10.0, 0.3, 1e-9, 100.0
    E_star = E / (1 - nu ** 2)
    m = rho * 4 / 3 * math.pi * R ** 3
    delta = (15 * m * v ** 2 / (16 * E_star * math.sqrt(R))) ** 0.4
    F = 4 / 3 * E_star * math.sqrt(R) * delta ** 1.5
    assert 0.4 * F * delta == pytest.approx(0.5 * m * v ** 2, rel=1e-12)      # spring energy = kinetic energy
    tol = 1e-12
    assert ref["delta_max"] == pytest.approx(delta, rel=tol)
    assert ref["F_max"] == pytest.approx(F, rel=tol)
    assert ref["t_c"] == pytest.approx(0.8 * beta(0.4, 0.5) * delta / v, rel=1e-10)
    assert ref["a"] == pytest.approx(math.sqrt(R * delta), rel=tol)
    assert ref["p0"] == pytest.approx(3 * F / (2 * math.pi * R * delta), rel=tol)
    assert ref == pytest.approx(ball.hertz())


@pytest.mark.slow
def test_rows_and_table(study):
    """Errors are value / Hertz - 1; the ball bounces off (energy kept: rebound speed within 1 % of v);
    the table has the header's columns on every row, Hertz's first."""
    rows = study[0]
    r = rows[0]
    for k in ("t_c", "F_max", "delta_max"):
        assert r[f"err_{k}"] == pytest.approx(r[k] / r["hertz"][k] - 1.0, rel=1e-12, abs=1e-15)
    assert r["released"] and abs(r["rebound"] - 1.0) < 0.01
    assert r["t_c"] == pytest.approx(round(r["t_c"] / r["dt"]) * r["dt"], rel=1e-9)    # resolved to dt
    table = hertz_report.html_rows(rows)
    assert len(table) == 1 + len(rows) and table[0][0] == "Hertz"
    assert all(len(row) == len(hertz_report.HEADER) for row in table)
    assert {"t_c (ms)", "err t_c", "F_max (N)", "err F_max", "δ_max (mm)", "err δ_max"} <= set(hertz_report.HEADER)


@pytest.mark.slow
def test_rerun_computes_nothing(study):
    rows, again, computed, path = study
    assert computed == 0
    assert [r["F_max"] for r in again] == [r["F_max"] for r in rows]
    # a changed definition (another dt) is not read as this row
    folder = path / hertz_report.run_name(*RUN[0])
    other = hertz_report.key_of(RUN[0][0], 2 * RUN[0][1])
    assert hertz_report.read_row(folder, other) is None


def test_verdict_follows_the_finest_level():
    """Agrees when the finest level's t_c and F_max are within 5 %, in part when one is."""
    def row(level, dt, et, ef):
        return {"level": level, "dt": dt, "a_over_h": 2.0 * level, "err_t_c": et, "err_F_max": ef,
                "err_delta_max": 0.0, "rebound": 1.0, "energy_max_dev": 1e-3}
    coarse = row(1, 4e-5, 0.08, -0.03)
    assert hertz_report.ours([coarse, row(3, 2e-5, 0.01, 0.0145)])[1] is Verdict.AGREES
    assert hertz_report.ours([row(3, 4e-5, 0.01, 0.01), row(3, 2e-5, 0.06, 0.01)])[1] is Verdict.IN_PART
    assert hertz_report.ours([coarse])[1] is Verdict.IN_PART
    text, verdict = hertz_report.ours([row(2, 2e-5, 0.06, -0.07)])
    assert verdict is Verdict.DISAGREES
    assert "t_c is not within and F_max not within 5 % of Hertz" in text


@pytest.mark.slow
def test_picture_of_the_finest_run(study, monkeypatch):
    """The picture reads the stored state of largest force: the ball presses on the plane, and the
    largest von Mises stress near the axis lies below the surface (matplotlib here: fast)."""
    monkeypatch.setenv("SDM_NO_PYVISTA", "1")
    path = study[3]
    if COMM.rank == 0:
        from sdm_dolfinx.validation import ball_pictures
        p = ball_pictures.picture_ball(path / hertz_report.run_name(*RUN[0]), path)
        assert (path / p["png"]).stat().st_size > 10_000 and p["renderer"] == "matplotlib"
        assert p["contact_force"] > 0.5 * p["p0"] * math.pi * p["a"] ** 2
        assert 0.0 < p["vm_depth"] < 2 * p["a"] and p["vm_axis_max"] > 0.3 * p["p0"]
        assert np.isfinite(p["vm_max"])
    COMM.Barrier()
