"""obstacles.xdmf written and read back (sdm_dolfinx/io/obstacle_xdmf.py) without a run: every grid at its
time with the obstacles' geometry there (a plane at s(t), a sphere at its radius), an obstacle that left
the box gives an empty grid, a step taken back is gone, a shape that is not written is named."""
import numpy as np
import pytest

from sdm_dolfinx.io.obstacle_xdmf import ObstacleWriter, read_obstacles
from sdm_dolfinx.obstacles import Ball, HalfSpace

BOX = (np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0]))


def test_a_round_trip(tmp_path):
    path = tmp_path / "obstacles.xdmf"
    plane = HalfSpace((0.0, 0.0, 0.1), (0.0, 0.0, 1.0), motion=lambda t: (0.0, 0.0, t / 3))
    ball = Ball((0.2, 0.0, 0.0), 0.5, motion=lambda t: (0.0, 0.0, 2 * t / 3))
    w = ObstacleWriter(path, [plane, ball], BOX)
    times = [0.0, 0.1, 1.2, 2.4, 3.6]
    for n, t in enumerate(times):
        w.write(10 * n, t)
    w.write(50, 4.8)
    w.drop(50)                                                    # taken back: as if never written
    grids = read_obstacles(path)
    assert [g["step"] for g in grids] == [0, 10, 20, 30, 40] and [g["t"] for g in grids] == times
    for g in grids:
        x, cells, which, t = g["points"], g["cells"], g["which"], g["t"]
        assert np.all((x >= BOX[0]) & (x <= BOX[1]))
        on_plane = np.unique(cells[which == 0])
        if t / 3 + 0.1 <= 1.0:
            assert len(on_plane) and np.max(np.abs(x[on_plane, 2] - (0.1 + t / 3))) <= 1e-15
        else:
            assert len(on_plane) == 0                                 # above the box
        sphere = np.unique(cells[which == 1])
        if t == 0.0:                                                  # inside the box: its vertices, exactly read
            r = np.linalg.norm(x[sphere] - [0.2, 0.0, 0.0], axis=1)
            assert np.max(np.abs(r - 0.5)) <= 1e-15
    assert len(grids[-1]["cells"]) == 0 and grids[-1]["points"].shape == (0, 3)          # everything left the box


def test_what_is_not_written_is_named_and_a_restart_writes_the_kept_steps(tmp_path):
    path = tmp_path / "obstacles.xdmf"
    lo, hi = np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 0.0])           # 2-D
    tilted = HalfSpace((0.0, 0.0, 0.0), (0.0, 1.0, 1.0))                     # not planar: not in 2-D
    floor = HalfSpace((0.0, -0.5), (0.0, 1.0), motion=lambda t: (0.0, t))
    w = ObstacleWriter(path, [floor, tilted], (lo, hi))
    w.write(0, 0.0)
    w.write(5, 0.5)
    again = ObstacleWriter(path, [floor, tilted], (lo, hi), kept=[(0, 0.0)])   # a restart from step 0
    again.write(3, 0.3)
    grids = read_obstacles(path)
    assert [(g["step"], g["t"]) for g in grids] == [(0, 0.0), (3, 0.3)]
    for g in grids:
        assert g["cells"].shape[1] == 2 and g["not_written"] == "half-space (obstacle 1)"
        assert g["points"][:, 1] == pytest.approx(-0.5 + g["t"], abs=1e-15)
        assert sorted(g["points"][:, 0]) == [-1.0, 1.0]                     # the floor across the box


def test_a_fixed_obstacle_is_written_once(tmp_path):
    """Fixed obstacles: the first grid holds the mesh, the others include it (read back the same)."""
    path = tmp_path / "obstacles.xdmf"
    w = ObstacleWriter(path, [Ball((0.0, 0.0, 0.0), 0.5)], BOX, kept=[(0, 0.0), (4, 0.4)])
    w.write(8, 0.8)
    grids = read_obstacles(path)
    assert [g["step"] for g in grids] == [0, 4, 8] and path.read_text().count("<xi:include") == 2
    assert path.read_text().count("<Geometry") == 1
    for g in grids:
        assert np.array_equal(g["points"], grids[0]["points"]) and np.array_equal(g["cells"], grids[0]["cells"])
        assert np.max(np.abs(np.linalg.norm(g["points"], axis=1) - 0.5)) <= 1e-15
