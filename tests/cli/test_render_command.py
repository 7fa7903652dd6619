"""The render command draws any 2-D or 3-D run folder with the obstacle its problem declares, puts
units on its colour bars, and refuses in one line (exit 2, nothing written) a time, a scale or a
file it would not draw as asked, and a folder it cannot write."""
import json
import math
import os
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli
from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.post import render

COMM = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def runs():
    """Short runs: the ball (3-D, P2 tetrahedra, level 1, 5 steps), a user's copy of the plane bar
    demo named otherwise (its wall x = 0), the membrane (N = 4) and the 1-D bar."""
    folder = Path(COMM.bcast(tempfile.mkdtemp(prefix="sdm_render_") if COMM.rank == 0 else None, root=0))
    wall_bar = folder / "wall_bar.py"
    if COMM.rank == 0:
        text = (ROOT / "demos" / "bar_problem.py").read_text()
        wall_bar.write_text(text.replace('name="plane_bar"', 'name="wall_bar"'))
    COMM.Barrier()
    out = {k: folder / k for k in ("ball", "bar2d", "membrane", "rod")}
    quiet = ["--quiet"]
    assert cli.main(["ball", "--level", "1", "--height", "0.001", "--dt", "4e-5", "--T", "2e-4", "--write-every", "1",
                     "--out", str(out["ball"])] + quiet) == 0
    assert cli.main(["run", "--problem-file", str(wall_bar), "--Nx", "20", "--Ny", "2", "--dt", "1e-6", "--T", "2.5e-5",
                     "--write-every", "5", "--out", str(out["bar2d"])] + quiet) == 0
    assert cli.main(["membrane", "--N", "4", "--dt", "0.01", "--T", "0.02", "--out", str(out["membrane"])] + quiet) == 0
    assert cli.main(["bar", "--NX", "4", "--dt", "0.05", "--T", "0.1", "--out", str(out["rod"])] + quiet) == 0
    yield out
    COMM.Barrier()
    if COMM.rank == 0:
        shutil.rmtree(folder, ignore_errors=True)


def _render(argv, capsys):
    """(exit status, stdout, stderr on rank 0) of ``render ARGV``."""
    status = cli.main(["render", *map(str, argv)])
    out, err = capsys.readouterr()
    return status, out, err


def _box(mask):
    """(x0, x1, y0, y1): the bounding box of the largest connected set of pixels of ``mask`` (the
    obstacle or the body; stray pixels of the same colour in the text's anti-aliasing, or the
    colour bar, left out)."""
    from scipy import ndimage
    labels, n = ndimage.label(mask)
    biggest = 1 + np.argmax(ndimage.sum(mask, labels, range(1, n + 1)))
    ys, xs = np.nonzero(labels == biggest)
    return xs.min(), xs.max(), ys.min(), ys.max()


def _grey_box(png):
    """The box of the obstacle: the picture's most frequent light grey (neither white nor the mesh's
    edges drawn over black), give or take 10 per channel."""
    import imageio.v2 as imageio
    a = imageio.imread(png)[..., :3].astype(int)
    greyish = (np.ptp(a, axis=2) < 16) & (a.min(axis=2) > 105) & (a.max(axis=2) < 200)     # not edges on black
    values, counts = np.unique(a[greyish], axis=0, return_counts=True)
    grey = values[np.argmax(counts)]
    return _box(np.all(np.abs(a - grey) <= 10, axis=2))


def _inferno_box(png):
    """The box of the strongly coloured pixels (the body, coloured by the inferno map)."""
    import imageio.v2 as imageio
    a = imageio.imread(png)[..., :3].astype(int)
    return _box((np.ptp(a, axis=2) > 60) & ~((a[..., 0] < 80) & (a[..., 2] > 150)))      # not cyan or blue


def test_a_3d_run_is_drawn(runs, mpi_tmp_path, capsys):
    """The ball (quadratic tetrahedra) in a PNG and a GIF: its surface coloured by the von Mises
    stress in N/mm^2 over the floor z = 0 its problem declares (a traceback before)."""
    png, gif = mpi_tmp_path / "ball.png", mpi_tmp_path / "ball.gif"
    status, out, err = _render([runs["ball"], "--png", png, "--gif", gif, "--size", "480", "240"], capsys)
    assert status == 0, err
    if COMM.rank == 0:
        assert err == "" and f"wrote {png} (t = 0.0002, " in out and f"wrote {gif} (6 frames, " in out, (out, err)
        assert png.stat().st_size > 5000 and gif.stat().st_size > 5000
        series = render.read_xdmf(runs["ball"])
        obstacle = render.obstacle_of(series)
        assert (obstacle["component"], obstacle["flat"], len(obstacle["points"])) == (2, 0.0, 172)
        look = render.Look(series, render.kind_of(series), 1.0, obstacle)
        assert look.colour_title == "von Mises stress\n(N/mm^2)" and "the obstacle z = 0" in look.title(0.0, 0, "c")
        if render.have_pyvista():
            x0, x1, y0, y1 = _grey_box(png)            # the floor: a wide slab in the left half
            assert x1 - x0 > 2 * (y1 - y0) and x1 < 260, (x0, x1, y0, y1)


def test_the_3d_surface_and_its_stress(runs):
    """The ball's drawn surface is closed (every edge in two triangles) and lies on the sphere;
    the stress of a linear displacement is exact: u = (a x, 0, 0) gives von Mises |2 mu a|... for
    nu = 0.3 the deviatoric norm of diag(lambda a + 2 mu a, lambda a, lambda a)."""
    if COMM.rank != 0:
        return
    series = render.read_xdmf(runs["ball"])
    tri = series.surface_triangles()
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    _, count = np.unique(edges, axis=0, return_counts=True)
    assert np.all(count == 2)
    r = np.linalg.norm(series.points[np.unique(tri)] - series.parameters["centre"], axis=1)
    assert np.allclose(r, series.parameters["radius"], rtol=1e-6)
    a = 1e-3
    u = np.zeros_like(series.points)
    u[:, 0] = a * series.points[:, 0]
    lam, mu = series.lame()
    s = np.array([lam * a + 2 * mu * a, lam * a, lam * a])
    expected = math.sqrt(1.5 * np.sum((s - s.mean()) ** 2))
    assert np.allclose(series.von_mises(u), expected, rtol=1e-9)
    assert np.allclose(series.nodal_von_mises(u), expected, rtol=1e-9)


def test_linear_tetrahedra_and_what_cannot_be_drawn(runs):
    """The ball's corner nodes as linear tetrahedra (what a P1 or P1+ run writes): a closed surface
    and the exact stress of a linear displacement; a scalar u on a 3-D mesh and hexahedra are
    refused in one line, a body without Lamé parameters is coloured by |u| (in its unit)."""
    if COMM.rank != 0:
        return
    p2 = render.read_xdmf(runs["ball"])
    p1 = render.Series(p2.points, p2.cells[:, :4], "Tetrahedron", p2.times, p2._datasets, p2._h5path, p2.run,
                       p2.xdmf)
    tri = p1.surface_triangles()
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    assert np.all(np.unique(edges, axis=0, return_counts=True)[1] == 2) and len(tri) * 4 == len(p2.surface_triangles())
    u = np.zeros_like(p1.points)
    u[:, 2] = 1e-3 * p1.points[:, 1]                             # a shear: von Mises sqrt(3) mu gamma
    assert np.allclose(p1.von_mises(u), math.sqrt(3) * p1.lame()[1] * 1e-3, rtol=1e-9)
    scalar = render.Series(p2.points, p2.cells, p2.cell_type, p2.times, p2._datasets, p2._h5path, p2.run, p2.xdmf)
    scalar.field = lambda name, t: np.zeros(len(p2.points))
    with pytest.raises(render.RenderError, match="a scalar u on a 3-D mesh"):
        render.kind_of(scalar)
    hexes = render.Series(p2.points, p2.cells[:, :8], "Hexahedron", p2.times, p2._datasets, p2._h5path, p2.run,
                          p2.xdmf)
    with pytest.raises(render.RenderError, match="cannot draw Hexahedron cells"):
        render.kind_of(hexes)
    run = json.loads(json.dumps(p2.run))
    del run["problem"]["parameters"]["lame_mu"]
    plain = render.Series(p2.points, p2.cells, p2.cell_type, p2.times, p2._datasets, p2._h5path, run, p2.xdmf)
    look = render.Look(plain, "solid3d", 1.0, {"none": "-"})
    assert look.colour_title == "displacement |u|\n(mm)"
    assert np.allclose(look.values(u), np.abs(u[:, 2]))


def test_a_wall_is_drawn_as_a_wall(runs, mpi_tmp_path, capsys, monkeypatch):
    """A user's plane bar (constraint x + u_x >= 0) hits the wall x = 0: drawn as a vertical band
    left of the bar, not a floor under it (pyvista, and matplotlib's vertical line)."""
    png = mpi_tmp_path / "bar.png"
    status, out, err = _render([runs["bar2d"], "--png", png], capsys)
    assert status == 0, err
    if COMM.rank != 0:
        return
    if render.have_pyvista():
        gx0, gx1, gy0, gy1 = _grey_box(png)
        bx0, bx1, by0, by1 = _inferno_box(png)
        assert gy1 - gy0 > 2 * (gx1 - gx0) and gx1 <= bx0 + 3 and gy0 < by0 and gy1 > by1, \
            ((gx0, gx1, gy0, gy1), (bx0, bx1, by0, by1))
    series = render.read_xdmf(runs["bar2d"])
    obstacle = render.obstacle_of(series)
    assert (obstacle["component"], obstacle["flat"]) == (0, 0.0)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig = plt.figure()
    look = render.Look(series, "solid", 1.0, obstacle)
    ax = render.render_mpl.mpl_draw(fig, series, series.times[-1], 1.0, look, look.range(series.times))
    lines = [line.get_xdata() for line in ax.lines if len(line.get_xdata()) == 2]
    assert any(list(x) == [0.0, 0.0] for x in lines)                          # axvline(0)
    assert fig.axes[-1].get_ylabel() == "von Mises stress (plane strain) (N/mm^2)"
    plt.close(fig)


def test_matplotlib_draws_every_kind(runs, mpi_tmp_path, monkeypatch):
    """Without pyvista: the ball's surface, the bar and the membrane, each with its units."""
    if COMM.rank != 0:
        return
    monkeypatch.setattr(render, "have_pyvista", lambda: False)
    for name in ("ball", "bar2d", "membrane"):
        png = mpi_tmp_path / f"{name}.png"
        assert render.picture(runs[name], png) == "matplotlib"
        assert png.stat().st_size > 10_000
    assert render.animation(runs["membrane"], mpi_tmp_path / "m.gif") == "matplotlib"
    series = render.read_xdmf(runs["membrane"])
    assert render.Look(series, "membrane", 10.0, render.obstacle_of(series)).colour_title == \
        "displacement u\n(dimensionless)"


def test_the_membrane_obstacle_is_the_declared_one(mpi_tmp_path):
    """The membrane's obstacle at its declared height; none without obstacle (the plane was drawn
    anyway before); a problem file changed since the run: not drawn, with a warning."""
    a, b = mpi_tmp_path / "low", mpi_tmp_path / "free"
    assert cli.main(["membrane", "--N", "4", "--dt", "0.01", "--T", "0.01", "--obstacle", "-0.01", "--quiet",
                     "--out", str(a)]) == 0
    assert cli.main(["membrane", "--N", "4", "--dt", "0.01", "--T", "0.01", "--no-obstacle", "--quiet",
                     "--out", str(b)]) == 0
    if COMM.rank != 0:
        return
    low = render.obstacle_of(render.read_xdmf(a))
    assert (low["component"], low["flat"], len(low["points"])) == (None, -0.01, 9)
    assert "none" in render.obstacle_of(render.read_xdmf(b))


def test_a_changed_problem_file_draws_no_obstacle(runs, mpi_tmp_path, capsys):
    """run.json names a problem file whose contents changed: the picture is drawn without the
    obstacle, a one-line warning says why."""
    copy = mpi_tmp_path / "copy"
    if COMM.rank == 0:
        shutil.copytree(runs["bar2d"], copy)
        info = json.loads((copy / "run.json").read_text())
        info["problem"]["source_sha256"] = "0" * 64
        (copy / "run.json").write_text(json.dumps(info))
    COMM.Barrier()
    if COMM.rank == 0:
        with pytest.warns(render.RenderWarning, match=r"^the obstacle is not drawn: its problem file .*wall_bar.py "
                                                      r"changed since the run$"):
            status, out, err = _render([copy, "--png", mpi_tmp_path / "c.png"], capsys)
    else:
        status, out, err = _render([copy, "--png", mpi_tmp_path / "c.png"], capsys)
    assert status == 0
    if COMM.rank == 0:
        assert err == "" and (mpi_tmp_path / "c.png").is_file()
        series = render.read_xdmf(copy)
        with pytest.warns(render.RenderWarning):
            obstacle = render.obstacle_of(series)
        look = render.Look(series, "solid", 1.0, obstacle)
        assert "the obstacle is not drawn (see the warning)" in look.title(0.0, 0, "cyan")


# (arguments after the run folder, the run, expected fragment of the one-line message)
BAD = [
    (["--png", "x.png", "--time", "nan"], "ball", "time nan is not a finite number"),
    (["--png", "x.png", "--time", "-5"], "ball", "time -5 is outside the run's output times [0, 0.0002]"),
    (["--png", "x.png", "--time", "1e308"], "ball", "time 1e+308 is outside the run's output times"),
    (["--png", "x.png", "--time", "inf"], "bar2d", "time inf is not a finite number"),
    (["--png", "x.png", "--scale", "inf"], "ball", "scale inf: the displacement magnification must be"),
    (["--png", "x.png", "--scale", "0"], "bar2d", "scale 0: "),
    (["--png", "x.png", "--scale", "-2"], "membrane", "scale -2: "),
    (["--png", "x.png", "--scale", "nan"], "membrane", "scale nan: "),
    (["--gif", "x.txt"], "ball", "x.txt: the file must end in .gif or .mp4"),
    (["--png", "x.jpg"], "bar2d", "x.jpg: the file must end in .png"),
    (["--gif", "x.gif", "--fps", "nan"], "membrane", "--fps"),
    (["--gif", "x.gif", "--every", "0"], "membrane", "--every"),
    (["--png", "x.png", "--size", "8", "8"], "membrane", "--size 8 8: each side from 16 to 8192 pixels"),
    (["--png", "x.png", "--size", "100000", "100000"], "membrane", "--size 100000 100000"),
    (["--gif", "x.gif", "--time", "0.01"], "membrane", "--time is used by --png, which is not given"),
    (["--merge", "--fps", "3"], "membrane", "--fps is used by --gif"),
    (["--merge", "--scale", "3"], "membrane", "--scale is used by --png or --gif"),
    ([], "membrane", "nothing to do"),
    (["--png", "x.png"], "rod", "is a 1-D run"),
    (["--png", "x.png"], None, "no solution.xdmf there"),
]


@pytest.mark.parametrize("argv,run,message", BAD)
def test_bad_input_is_refused(argv, run, message, runs, mpi_tmp_path, capsys, monkeypatch):
    """Exit 2, one line naming the problem, no traceback, nothing written (neither in the run
    folder nor in the current one)."""
    folder = runs[run] if run else mpi_tmp_path / "nothing"
    before = sorted(os.listdir(folder)) if run and COMM.rank == 0 else None
    cwd = mpi_tmp_path / "cwd"
    if COMM.rank == 0:
        cwd.mkdir()
    COMM.Barrier()
    monkeypatch.chdir(cwd)
    status, out, err = _render([folder, *argv], capsys)
    assert status == 2
    if COMM.rank == 0:
        assert err.startswith("python -m sdm_dolfinx render: error: ") and err.count("\n") == 1, err
        assert message in err and "Traceback" not in err, err
        assert out == "" and not list(cwd.iterdir())
        assert before is None or sorted(os.listdir(folder)) == before


def test_the_api_refuses_too(runs, mpi_tmp_path):
    """render.picture and render.animation raise a RenderError (an SdmError) and write nothing."""
    if COMM.rank != 0:
        return
    for kwargs in ({"time": float("nan")}, {"time": -5.0}, {"scale": float("inf")}):
        with pytest.raises(SdmError):
            render.picture(runs["bar2d"], mpi_tmp_path / "p.png", **kwargs)
    with pytest.raises(render.RenderError, match="must end in .gif or .mp4"):
        render.animation(runs["bar2d"], mpi_tmp_path / "x.txt")
    with pytest.raises(render.RenderError, match="1-D run"):
        render.picture(runs["rod"], mpi_tmp_path / "r.png")
    assert not list(mpi_tmp_path.iterdir())


def test_an_mp4_without_its_writer_is_refused(runs, mpi_tmp_path, capsys):
    """--gif x.mp4 needs imageio-ffmpeg (pyvista) or ffmpeg (matplotlib): refused up front, not after
    drawing every frame."""
    import importlib.util
    from matplotlib.animation import FFMpegWriter
    if (importlib.util.find_spec("imageio_ffmpeg") if render.have_pyvista() else FFMpegWriter.isAvailable()):
        pytest.skip("this machine can write MP4")
    status, out, err = _render([runs["membrane"], "--gif", mpi_tmp_path / "m.mp4"], capsys)
    assert status == 2
    if COMM.rank == 0:
        assert "an MP4 needs" in err and err.count("\n") == 1 and not (mpi_tmp_path / "m.mp4").exists()


@pytest.mark.parametrize("argv", [["--merge"], ["--png", "{run}/p.png"]])
def test_a_read_only_folder_is_refused(argv, runs, capsys, read_only):
    """--merge (or a picture) into a folder that cannot be written: one line, exit 2 (an
    internal error before)."""
    folder = runs["membrane"]
    argv = [a.format(run=folder) for a in argv]
    read_only(folder, True)
    try:
        status, out, err = _render([folder, *argv], capsys)
    finally:
        read_only(folder, False)
    assert status == 2
    if COMM.rank == 0:
        assert err.startswith("python -m sdm_dolfinx render: error: cannot write") and err.count("\n") == 1, err
        assert not (folder / "solution_paraview.xdmf").exists() and not (folder / "p.png").exists()


def test_bodies_are_tagged_and_coloured(mpi_tmp_path, capsys, monkeypatch):
    """A run with ``bodies`` writes the cell field ``body`` (k on the k-th body's cells: here the striker's
    cells, x < 0, are 1 and the struck bar's 2, found from the cells' own coordinates) with the bodies' names
    in run.json, and render draws each body's edges in its colour with their names (pyvista and matplotlib)."""
    out = mpi_tmp_path / "bars"
    assert cli.main(["run", "--problem-file", str(ROOT / "demos" / "two_bars_problem.py"), "--Nx", "10", "--Ny", "2",
                     "--dt", "5e-7", "--T", "5e-6", "--out", str(out), "--quiet"]) == 0
    series = render.read_xdmf(out)
    t = series.times[-1]
    centre_x = series.points[series.cells, 0].mean(axis=1)
    np.testing.assert_array_equal(series.field("body", t).reshape(-1), np.where(centre_x < 0.0, 1.0, 2.0))
    tag, names = series.node_bodies(t)
    assert names == ["striker", "struck"] and set(tag[series.points[:, 0] < 0]) == {1} and \
        set(tag[series.points[:, 0] > 0]) == {2}
    for backend in ("pyvista", "matplotlib"):
        if backend == "matplotlib":
            monkeypatch.setattr(render, "have_pyvista", lambda: False)
        elif not render.have_pyvista():
            continue
        png = mpi_tmp_path / f"{backend}.png"
        status, _, err = _render([out, "--png", png], capsys)
        assert status == 0, err
        if COMM.rank == 0:
            import matplotlib.image as mpimg
            a = np.rint(255 * mpimg.imread(png)[..., :3]).astype(int)
            for colour in ("#1f77b4", "#2ca02c"):          # the striker's and the struck bar's edges
                rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])
                assert np.count_nonzero(np.all(np.abs(a - rgb) <= 12, axis=2)) > 100, (backend, colour)
