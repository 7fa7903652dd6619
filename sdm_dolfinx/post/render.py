"""Pictures and animations of a run from its ``solution.xdmf`` (optional helpers).

Everything here reads the files a run wrote (``solution.xdmf`` + ``.h5``, ``run.json``), so it
works the same for runs made with the command line or the Python API, on any number of ranks
(call it on one rank: Debian's h5py is serial).

:func:`picture` and :func:`animation` render a warped membrane over its obstacle, or a
deformed elastic body coloured by its von Mises stress, with pyvista off-screen when it is
installed (``pip install pyvista imageio``; its VTK wheel renders through EGL/OSMesa without a
display) and with matplotlib otherwise (:mod:`.render_mpl`). Reading the files and the
ParaView-friendly XDMF are in :mod:`sdm_dolfinx.io.xdmf_reader`; their names are available here as well
(``render.read_xdmf``, ``render.merge_xdmf``, ...).

The command is ``python -m sdm_dolfinx render RUN_DIR [--png F] [--gif F] [--time T]
[--merge]`` (:mod:`sdm_dolfinx.cli.render`); running this file is only the pyvista child
process (see :func:`_in_child`).

This module, :mod:`sdm_dolfinx.io.xdmf_reader` and :mod:`.render_mpl` import only the standard library at load time
(numpy, h5py, pyvista and matplotlib inside the functions), so a ParaView ``pvpython`` script
can load this file by path; it then loads those two by path too.
"""
import json
import os
import subprocess
import sys
from pathlib import Path


def _load_sibling(relative):
    """The module at ``relative`` (a path from this file's folder), loaded by path (no package
    import: see above)."""
    import importlib.util
    path = Path(__file__).resolve().parent / relative
    spec = importlib.util.spec_from_file_location(f"sdm_render_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


if __package__:            # imported as sdm_dolfinx.post.render
    from sdm_dolfinx.post import render_mpl
    from sdm_dolfinx.io import xdmf_reader as xdmf
else:                      # loaded by path (pvpython, the pyvista child process)
    xdmf, render_mpl = _load_sibling("../io/xdmf_reader.py"), _load_sibling("render_mpl.py")

# the names demos, tests and the paper use as render.<name>
Series, read_xdmf, merge_xdmf, merged_path, von_mises = (xdmf.Series, xdmf.read_xdmf, xdmf.merge_xdmf,
                                                          xdmf.merged_path, xdmf.von_mises)
p2_edge_lines, draw_foundation, draw_disc_mesh = (render_mpl.p2_edge_lines, render_mpl.draw_foundation,
                                                  render_mpl.draw_disc_mesh)

#: Xdmf topology name -> (VTK cell type, nodes per cell)
_CELLS = {"Triangle": (5, 3), "Triangle_6": (22, 6), "Quadrilateral": (9, 4), "Tetrahedron": (10, 4)}


def have_pyvista():
    """True when pyvista is installed (checked without importing it, see :func:`_in_child`)."""
    import importlib.util
    return importlib.util.find_spec("pyvista") is not None


def _in_child():
    """True when pyvista must render in a fresh process.

    dolfinx loads its libraries with RTLD_GLOBAL; VTK's PyPI wheels (manylinux, old C++ string
    ABI) loaded afterwards bind their std::regex instantiations to dolfinx's (new ABI) and abort
    with std::bad_alloc as soon as a colour bar is drawn. Loading VTK first avoids it; when
    dolfinx is already there, the picture is made by ``python render.py`` in a child process.
    """
    return "dolfinx" in sys.modules and "vtkmodules.vtkCommonCore" not in sys.modules


def _run_child(what, kwargs, xdmf):
    """Draw in a fresh process: ``python -P render.py WHAT XDMF KWARGS_JSON`` (see :func:`_child`)."""
    cmd = [sys.executable, "-P", str(Path(__file__).resolve()), what, str(xdmf), json.dumps(kwargs)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"rendering in a child process failed ({' '.join(cmd)}):\n{p.stderr[-2000:]}")
    return "pyvista"


def _pv_grid(series, tri=True):
    import numpy as np
    import pyvista as pv
    cells = series.linear_triangles() if tri else series.cells
    vtk_type = 5 if tri else _CELLS[series.cell_type][0]
    k = cells.shape[1]
    conn = np.hstack([np.full((len(cells), 1), k), cells]).ravel()
    return pv.UnstructuredGrid(conn, np.full(len(cells), vtk_type, dtype=np.uint8), series.points.copy())


def _pv_setup():
    import pyvista as pv
    pv.OFF_SCREEN = True
    # a VTK wheel tries X first and warns when there is none; go straight to EGL then
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    return pv


def _kind(series):
    """``"membrane"`` for a scalar displacement, ``"solid"`` for a vector one."""
    return "membrane" if series.field("displacement", 0.0).ndim == 1 else "solid"


def _unit(series, key):
    """The unit of ``key`` from run.json's ``problem.units`` (first word), "dimensionless", or ""."""
    units = series.run.get("problem", {}).get("units", {})
    if key in units and units[key].split():
        return units[key].split()[0]
    if str(units.get("all", "")).startswith("dimensionless"):
        return "dimensionless"
    return ""


def _time_label(series, t):
    """``t = 0.300`` (dimensionless) or ``t = 12.50 ms`` (a run in seconds shorter than 1 s)."""
    t = series.times[series.index(t)]
    if _unit(series, "t") == "s" and series.times[-1] < 1.0:
        return f"t = {1e3 * t:.2f} ms"
    return f"t = {t:.3f}" + (f" {_unit(series, 't')}" if _unit(series, "t") not in ("", "dimensionless") else "")


# ------------------------------------------------------------------------ the membrane
def _membrane_frame_pv(plotter, series, t, scale, clim):
    import numpy as np
    pv = _pv_setup()
    u = series.field("displacement", t)
    active = (series.field("active", t) > 0.5) & series.vertex_mask()
    grid = _pv_grid(series)
    grid.points[:, 2] = scale * u
    grid.point_data["displacement"] = u
    obstacle = float(series.parameters.get("obstacle", 0.0))
    x0, x1 = series.points[:, 0].min(), series.points[:, 0].max()
    y0, y1 = series.points[:, 1].min(), series.points[:, 1].max()
    # the obstacle drawn a hair below its height, so that the membrane lying on it stays visible
    lift = 2e-3 * max(x1 - x0, y1 - y0)
    plane = pv.Plane(center=((x0 + x1) / 2, (y0 + y1) / 2, scale * obstacle - lift), direction=(0, 0, 1),
                     i_size=1.3 * (x1 - x0), j_size=1.3 * (y1 - y0))
    plotter.add_mesh(plane, color="#8c8c8c", opacity=1.0, name="obstacle")
    unit = _unit(series, "u_probe")
    plotter.add_mesh(grid, scalars="displacement", cmap="viridis", clim=clim, show_edges=True,
                     edge_color="#404040", line_width=0.5, name="membrane",
                     scalar_bar_args={"title": "displacement u" + (f"\n({unit})" if unit else "") + "\n",
                                      "vertical": True, "fmt": "%.3f", "color": "black", "position_x": 0.87,
                                      "position_y": 0.25, "title_font_size": 16, "label_font_size": 14})
    if active.any():
        pts = grid.points[active] + [0.0, 0.0, lift]
        plotter.add_mesh(pv.PolyData(pts), color="red", point_size=10, render_points_as_spheres=True,
                         name="active")
    else:
        plotter.remove_actor("active")
    plotter.add_text(f"membrane, {_time_label(series, t)}: vertical scale x{scale:g}; grey: obstacle; "
                     f"red: vertices in contact ({int(np.sum(active))})", font_size=11, name="title",
                     color="black")


def _membrane_camera(plotter, series, scale):
    """A view from a low corner: the obstacle plane in front, the membrane sagging onto it."""
    import numpy as np
    p = series.points
    c = p.mean(axis=0)
    size = max(np.ptp(p[:, 0]), np.ptp(p[:, 1]))
    plotter.camera_position = [(c[0] + 1.25 * size, c[1] - 2.2 * size, 0.95 * size), (c[0], c[1] + 0.05 * size, 0.0),
                               (0, 0, 1)]
    plotter.camera.view_angle = 24.0
    plotter.reset_camera()
    plotter.camera.zoom(1.25)


# ------------------------------------------------------------------------ elastic bodies
def _solid_frame_pv(plotter, series, t, scale, clim, lame):
    import numpy as np
    pv = _pv_setup()
    u = series.field("displacement", t)
    grid = _pv_grid(series)
    grid.points[:, :2] += scale * u[:, :2]
    grid.cell_data["stress"] = von_mises(series, u, *lame)
    grid = grid.cell_data_to_point_data()          # nodal averages: a smooth picture of a P1 stress
    unit = _unit(series, "lame_mu")
    title = "von Mises\nstress" + (f"\n({unit})" if unit else "") + "\n"
    font = max(10, round(16 * plotter.window_size[0] / 900))      # smaller in a small animation frame
    plotter.add_mesh(grid, scalars="stress", cmap="inferno", clim=clim, name="body",
                     scalar_bar_args={"title": title, "vertical": True, "position_x": 0.83, "position_y": 0.2,
                                      "width": 0.08, "height": 0.6, "fmt": "%.3g", "color": "black",
                                      "title_font_size": font, "label_font_size": font - 2, "n_labels": 5})
    plotter.add_mesh(_edges(series, u, scale), color="white", opacity=0.35, line_width=0.6, name="edges")
    active = series.field("active", t) > 0.5
    active[~series.vertex_mask()] = False           # midside nodes carry interpolated flags
    if active.any():
        plotter.add_mesh(pv.PolyData(grid.points[active]), color="cyan", point_size=9,
                         render_points_as_spheres=True, name="active")
    else:
        plotter.remove_actor("active")
    plotter.add_text(f"{series.problem_name or 'body'}, {_time_label(series, t)}: "
                     f"vertices in contact (cyan): {int(np.sum(active))}"
                     + (", true scale" if scale == 1 else f", displacement x{scale:g}"), font_size=11, name="title",
                     color="black")


def _edges(series, u, scale):
    """The mesh's (straight) cell edges at the deformed position."""
    import numpy as np
    pv = _pv_setup()
    c = series.cells[:, :3]
    e = np.unique(np.sort(np.concatenate([c[:, [0, 1]], c[:, [1, 2]], c[:, [2, 0]]]), axis=1), axis=0)
    pts = series.points.copy()
    pts[:, :2] += scale * u[:, :2]
    return pv.PolyData(pts, lines=np.hstack([np.full((len(e), 1), 2), e]).ravel())


def _foundation_pv(plotter, series, name):
    """The rigid support: the line y = 0 (disc) or x = 0 (the demos' plane_bar), as a hatched-grey band."""
    import numpy as np
    pv = _pv_setup()
    p = series.points
    span = np.ptp(p[:, :2], axis=0).max()
    if name == "plane_bar":
        box = pv.Box(bounds=(-0.05 * span, 0.0, p[:, 1].min() - 0.3 * np.ptp(p[:, 1]),
                             p[:, 1].max() + 0.3 * np.ptp(p[:, 1]), -0.01, 0.0))
    else:
        x0, x1 = p[:, 0].min(), p[:, 0].max()
        box = pv.Box(bounds=(x0 - 0.1 * span, x1 + 0.1 * span, -0.05 * span, 0.0, -0.01, 0.0))
    plotter.add_mesh(box, color="#9a9a9a", name="foundation")



def _solid_view(plotter, series, times, scale):
    """A fixed 2-D camera framing the body over all ``times`` (and its support)."""
    import numpy as np
    p = series.points
    lo = np.min([p[:, :2] + scale * series.field("displacement", t)[:, :2] for t in times], axis=(0, 1))
    hi = np.max([p[:, :2] + scale * series.field("displacement", t)[:, :2] for t in times], axis=(0, 1))
    lo, hi = np.minimum(lo, 0.0), hi
    c = 0.5 * (lo + hi)
    height = max(hi[1] - lo[1], (hi[0] - lo[0]) * 0.75)
    w, h = plotter.window_size
    # half the visible height: the body with headroom for the title, and (in a narrow window) its width
    # within the left 78 % of the picture, the colour bar taking the right-hand side
    scale_ = max(0.66 * height, (hi[0] - lo[0]) / (0.78 * 2 * w / h))
    width = 2 * scale_ * w / h
    c[1] += 0.05 * height
    c[0] = min(c[0] + 0.1 * width, lo[0] - 0.03 * width + 0.5 * width)
    plotter.view_xy()
    plotter.camera.focal_point = (c[0], c[1], 0.0)
    plotter.camera.position = (c[0], c[1], 10.0 * np.ptp(np.r_[lo, hi]))
    plotter.camera.parallel_projection = True
    plotter.camera.parallel_scale = scale_


# ------------------------------------------------------------------------ public API
def picture(run, png, time=None, scale=None, size=(900, 700)):
    """A PNG of a run at one output time (default: the last): pyvista if installed, else matplotlib.

    Membrane runs: the membrane warped by its displacement (``scale``, default 10) over the
    obstacle plane, coloured by the displacement, with the vertices in contact in red.
    Elastic bodies (disc, bar, any vector problem with ``lame_lambda``/``lame_mu`` in its
    parameters): the deformed body (``scale``, default 1 = true scale) coloured by the
    plane-strain von Mises stress, with the rigid support.

    Args:
        run: the run folder or its ``solution.xdmf``, or a :class:`Series`.
        png: output file.
        time: the output time to draw (nearest stored one).
        scale: displacement magnification.
        size: picture size in pixels.

    Returns:
        ``"pyvista"`` or ``"matplotlib"``: which one drew it.
    """
    series = run if isinstance(run, Series) else read_xdmf(run)
    t = series.times[-1] if time is None else time
    kind = _kind(series)
    scale = (10.0 if kind == "membrane" else 1.0) if scale is None else scale
    if not have_pyvista():
        render_mpl.picture_mpl(series, png, t, scale, kind)
        return "matplotlib"
    if _in_child():
        return _run_child("picture", {"png": str(Path(png).resolve()), "time": t, "scale": scale,
                                      "size": list(size)}, series.xdmf)
    pv = _pv_setup()
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    plotter.set_background("white")
    if kind == "membrane":
        u = series.field("displacement", t)
        _membrane_frame_pv(plotter, series, t, scale, [0.0, max(u.max(), 1e-12)])
        _membrane_camera(plotter, series, scale)
    else:
        lame = series.lame()
        _foundation_pv(plotter, series, series.problem_name)
        _solid_frame_pv(plotter, series, t, scale, series.stress_range([t]), lame)
        _solid_view(plotter, series, [t], scale)
    plotter.screenshot(str(png))
    plotter.close()
    return "pyvista"


def animation(run, path, times=None, scale=None, size=(640, 640), fps=12):
    """A GIF (or MP4 if ``path`` ends in .mp4 and imageio-ffmpeg is installed) of a run.

    Args:
        run: the run folder or its ``solution.xdmf``, or a :class:`Series`.
        path: output file.
        times: output times to show (default: all stored ones).
        scale: displacement magnification (see :func:`picture`).
        size: frame size in pixels.
        fps: frames per second.

    Returns:
        ``"pyvista"`` or ``"matplotlib"``.
    """
    series = run if isinstance(run, Series) else read_xdmf(run)
    times = list(series.times if times is None else times)
    kind = _kind(series)
    scale = (10.0 if kind == "membrane" else 1.0) if scale is None else scale
    if not have_pyvista():
        render_mpl.animation_mpl(series, path, times, scale, kind, fps)
        return "matplotlib"
    if _in_child():
        return _run_child("animation", {"path": str(Path(path).resolve()), "times": list(times), "scale": scale,
                                        "size": list(size), "fps": fps}, series.xdmf)
    import imageio.v2 as imageio
    pv = _pv_setup()
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    plotter.set_background("white")
    if kind == "membrane":
        top = max(float(series.field("displacement", t).max()) for t in times)
        clim = [0.0, top]
    else:
        lame = series.lame()
        clim = series.stress_range(times)
        _foundation_pv(plotter, series, series.problem_name)
    frames = []
    for i, t in enumerate(times):
        if kind == "membrane":
            _membrane_frame_pv(plotter, series, t, scale, clim)
            if i == 0:
                _membrane_camera(plotter, series, scale)
        else:
            _solid_frame_pv(plotter, series, t, scale, clim, lame)
            if i == 0:
                _solid_view(plotter, series, times, scale)
        plotter.render()
        frames.append(plotter.screenshot(return_img=True))
    plotter.close()
    if str(path).endswith(".mp4"):
        imageio.mimsave(str(path), frames, fps=fps)
    else:
        imageio.mimsave(str(path), frames, duration=1000.0 / fps, loop=0)
    return "pyvista"


def _child(argv):
    """The child process of :func:`_run_child`: ``picture`` or ``animation`` of XDMF with the
    JSON keyword arguments (the public command is ``python -m sdm_dolfinx render``)."""
    what, src, kwargs = argv
    kwargs = json.loads(kwargs)
    kwargs["size"] = tuple(kwargs["size"])
    {"picture": picture, "animation": animation}[what](read_xdmf(src), **kwargs)
    return 0


if __name__ == "__main__":
    raise SystemExit(_child(sys.argv[1:]))
