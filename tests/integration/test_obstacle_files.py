"""A problem's ``obstacles`` in the run folder and in the pictures: ``obstacles.xdmf`` holds them at every
written step (read back with their geometry at that step's time: a circle's points at its radius from its
centre, a moving plane's points on (x - p).n = s(t).n), a restart writes it again from the steps it keeps,
ParaView reads it, and ``render`` draws them (fixed, and a moving one at each picture's or frame's time).
Runs: demos/bowl_problem.py (a fixed bowl), tests/integration/rising_floor_problem.py (a rising floor and
a fixed disc/sphere beside the body, 2-D and 3-D). 1 and 2 ranks."""
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli
from sdm_dolfinx.io.obstacle_xdmf import read_obstacles
from sdm_dolfinx.post import render

COMM = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parents[2]
FLOOR = Path(__file__).resolve().parent / "rising_floor_problem.py"
LIFT, OMEGA = 0.5, 200.0
#: the bowl demo's defaults: disc radius r, bowl radius Rb (centre (0, Rb - r))
R, RB = 10.0, 40.0


def s(t):
    """The rising floor's height at the time t (rising_floor_problem.py)."""
    return LIFT * (1.0 - np.cos(OMEGA * t))


@pytest.fixture(scope="module")
def runs():
    folder = Path(COMM.bcast(tempfile.mkdtemp(prefix="sdm_obstacle_files_") if COMM.rank == 0 else None, root=0))
    out = {k: folder / k for k in ("bowl", "floor2d", "floor3d")}
    quiet = ["--quiet"]
    assert cli.main(["run", "--problem-file", str(ROOT / "demos" / "bowl_problem.py"), "--h", "2.5", "--dt", "5e-4",
                     "--T", "5e-3", "--write-every", "4", "--out", str(out["bowl"])] + quiet) == 0
    assert cli.main(["run", "--problem-file", str(FLOOR), "--dt", "2e-4", "--T", "4e-3", "--write-every", "5",
                     "--out", str(out["floor2d"])] + quiet) == 0
    assert cli.main(["run", "--problem-file", str(FLOOR), "--dim", "3", "--dt", "4e-5", "--T", "2e-4",
                     "--write-every", "2", "--out", str(out["floor3d"])] + quiet) == 0
    yield out
    COMM.Barrier()
    if COMM.rank == 0:
        shutil.rmtree(folder, ignore_errors=True)


def _grids(run):
    """The grids of obstacles.xdmf, their steps the same as solution.xdmf's times (checked)."""
    grids = read_obstacles(run)
    dt = render.read_xdmf(run).run["dt"]
    assert [g["t"] for g in grids] == pytest.approx(render.read_xdmf(run).times, rel=0, abs=1e-15)
    assert all(g["t"] == g["step"] * dt for g in grids)
    return grids


def test_a_fixed_bowl_is_written_at_every_step(runs):
    """The bowl (a circle of radius Rb about (0, Rb - r)): every point on it (those where the box cuts
    the polyline within its chords' sag Rb (1 - cos(pi / 360))), the same at every written step."""
    if COMM.rank != 0:
        return
    grids = _grids(runs["bowl"])
    assert [g["step"] for g in grids] == [0, 4, 8, 10]
    for g in grids:
        x, cells = g["points"], g["cells"]
        assert cells.shape[1] == 2 and len(cells) > 50 and set(g["which"]) == {0} and not g["not_written"]
        r = np.linalg.norm(x - [0.0, RB - R, 0.0], axis=1)
        exact = np.abs(r - RB) <= 1e-12 * RB
        assert exact.sum() >= len(r) - 2                              # the two ends cut by the box
        assert np.max(np.abs(r - RB)) <= RB * (1 - np.cos(np.pi / 360))
        assert np.array_equal(x, grids[0]["points"]) and np.array_equal(cells, grids[0]["cells"])
        assert np.all(x[:, 2] == 0.0) and x[:, 1].min() == pytest.approx(-R, abs=1e-12)     # the bowl's bottom


@pytest.mark.parametrize("dim", [2, 3])
def test_a_rising_floor_is_where_it_is_at_each_step(runs, dim):
    """The floor (obstacle 0) at y (2-D) or z (3-D) = s(t_n) at every written step; the fixed disc/sphere
    (obstacle 1) at its radius from its centre."""
    if COMM.rank != 0:
        return
    grids = _grids(runs[f"floor{dim}d"])
    assert len(grids) == (5 if dim == 2 else 4)
    centre, radius = ((30.0, 5.0, 0.0), 2.0) if dim == 2 else ((30.0, 0.0, 20.0), 4.0)
    for g in grids:
        x, cells, which = g["points"], g["cells"], g["which"]
        assert cells.shape[1] == dim and set(which) == {0, 1}
        floor = np.unique(cells[which == 0])
        assert np.max(np.abs(x[floor, dim - 1] - s(g["t"]))) <= 1e-12
        ball = np.unique(cells[which == 1])
        assert np.max(np.abs(np.linalg.norm(x[ball] - centre, axis=1) - radius)) <= 1e-12 * radius
    heights = [g["points"][np.unique(g["cells"][g["which"] == 0]), dim - 1].mean() for g in grids]
    assert np.all(np.diff(heights) > 0)                              # it rises


def test_a_restart_writes_the_kept_steps_again(runs):
    """A run extended with --restart: obstacles.xdmf holds its steps (the solution's) at their times."""
    run = runs["floor2d"]
    copy = Path(COMM.bcast(tempfile.mkdtemp(prefix="sdm_obstacle_restart_") if COMM.rank == 0 else None, root=0))
    if COMM.rank == 0:
        shutil.copytree(run, copy / "run")
    COMM.Barrier()
    assert cli.main(["run", "--restart", str(copy / "run"), "--T", "6e-3", "--quiet"]) == 0
    if COMM.rank == 0:
        grids = _grids(copy / "run")
        assert [g["step"] for g in grids] == [0, 5, 10, 15, 20, 25, 30]
        for g in grids:
            floor = np.unique(g["cells"][g["which"] == 0])
            assert np.max(np.abs(g["points"][floor, 1] - s(g["t"]))) <= 1e-12
        shutil.rmtree(copy, ignore_errors=True)
    COMM.Barrier()


def test_a_run_without_obstacles_leaves_none_behind(runs):
    """--overwrite with a problem that declares none: the previous run's obstacles.xdmf is removed."""
    copy = Path(COMM.bcast(tempfile.mkdtemp(prefix="sdm_obstacle_overwrite_") if COMM.rank == 0 else None, root=0))
    if COMM.rank == 0:
        shutil.copytree(runs["floor2d"], copy / "run")
    COMM.Barrier()
    assert (copy / "run" / "obstacles.xdmf").is_file()
    assert cli.main(["run", "--problem", "block", "--nx", "4", "--ny", "2", "--constrain", "nodes", "--dt", "2e-4",
                     "--T", "4e-4", "--out", str(copy / "run"), "--overwrite", "--quiet"]) == 0
    assert not (copy / "run" / "obstacles.xdmf").exists()
    COMM.Barrier()
    if COMM.rank == 0:
        shutil.rmtree(copy, ignore_errors=True)


def _grey(png):
    """The number of pixels of the obstacles' grey (render_pv.GREY or matplotlib's 0.5/0.6) in ``png``."""
    import matplotlib.image as mpimg
    img = (mpimg.imread(png)[:, :, :3] * 255).round()
    greys = np.array([[0x9a] * 3, [128] * 3, [153] * 3, [179] * 3])
    near = np.min(np.abs(img[:, :, None, :] - greys[None, None]).max(axis=3), axis=2) <= 6
    return int(near.sum())


@pytest.mark.parametrize("name", ["bowl", "floor2d", "floor3d"])
def test_render_draws_them(runs, name, mpi_tmp_path, capsys):
    """render --png and --gif: a picture with the obstacles in grey and named in the title; the
    moving floor at the picture's time and at every frame's."""
    png, gif = mpi_tmp_path / f"{name}.png", mpi_tmp_path / f"{name}.gif"
    status = cli.main(["render", str(runs[name]), "--png", str(png), "--gif", str(gif), "--time", "0"])
    out, err = capsys.readouterr()
    assert status == 0, err
    if COMM.rank != 0:
        return
    assert "not drawn" not in err
    assert png.stat().st_size > 10_000 and gif.stat().st_size > 10_000
    bare = mpi_tmp_path / f"{name}_bare.png"                        # the same picture without the obstacles
    render.picture(runs[name], bare, time=0.0, obstacle={"none": "left out by the test"})
    assert _grey(png) - _grey(bare) > 500
    series = render.read_xdmf(runs[name])
    obstacle = render.obstacle_of(series, 0.0)
    assert "shapes" in obstacle and obstacle["note"].startswith("grey: the obstacle")
    if name == "bowl":
        assert not obstacle["moving"] and len(obstacle["shapes"]) == 1
        return
    dim = 2 if name == "floor2d" else 3
    frames = render.obstacle_of(series, times=series.times)
    assert obstacle["moving"] and [f["time"] for f in frames["shapes"]] == series.times
    for shape in frames["shapes"] + obstacle["shapes"]:
        x = np.asarray(shape["points"])
        floor = np.abs(x[:, dim - 1] - s(shape["time"])) <= 1e-12
        assert floor.sum() >= (2 if dim == 2 else 3)
        assert np.all(floor | (x[:, 0] > 20.0))                        # else the disc/sphere beside the body


def test_matplotlib_draws_them_too(runs, mpi_tmp_path, monkeypatch):
    if COMM.rank != 0:
        return
    monkeypatch.setattr(render, "have_pyvista", lambda: False)
    for name in ("bowl", "floor3d"):
        png, bare = mpi_tmp_path / f"{name}.png", mpi_tmp_path / f"{name}_bare.png"
        assert render.picture(runs[name], png) == "matplotlib"
        render.picture(runs[name], bare, obstacle={"none": "left out by the test"})
        assert _grey(png) - _grey(bare) > 500


def _clean_env():
    keep = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM")
    return {k: v for k, v in os.environ.items()
            if k in keep or not k.startswith(("OMPI_", "PMIX_", "OPAL_", "PRTE_", "HYDRA_", "PMI_"))}


PV_SCRIPT = """
import sys
from paraview.simple import Xdmf3ReaderS, servermanager
r = Xdmf3ReaderS(FileName=[sys.argv[1]])
r.UpdatePipelineInformation()
for t in r.TimestepValues:
    r.UpdatePipeline(t)
    d = servermanager.Fetch(r)
    b = d.GetBounds()
    print(repr(t), d.GetNumberOfCells(), d.GetCellData().GetArray("obstacle") is not None, b[2], b[3], b[4], b[5])
"""


@pytest.mark.paraview
@pytest.mark.skipif(shutil.which("pvpython") is None, reason="ParaView is not installed")
@pytest.mark.parametrize("name", ["bowl", "floor3d"])
def test_paraview_reads_obstacles_xdmf(runs, name):
    """ParaView's XDMF reader: the written times, each grid's cells and its ``obstacle`` array, and (the
    moving floor) its lowest point at s(t) (single precision)."""
    if COMM.rank != 0:
        return
    grids = read_obstacles(runs[name])
    p = subprocess.run(["pvpython", "-c", PV_SCRIPT, str(runs[name] / "obstacles.xdmf")], capture_output=True,
                       text=True, env=_clean_env(), timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    rows = [line.split() for line in p.stdout.splitlines() if line.strip()]
    assert [float(r[0]) for r in rows] == pytest.approx([g["t"] for g in grids], abs=1e-15)
    assert [int(r[1]) for r in rows] == [len(g["cells"]) for g in grids]
    assert all(r[2] == "True" for r in rows)
    if name == "floor3d":
        assert [float(r[5]) for r in rows] == pytest.approx([g["points"][:, 2].min() for g in grids], abs=1e-6)
        assert [float(r[5]) for r in rows] == pytest.approx([s(g["t"]) for g in grids], abs=1e-6)
