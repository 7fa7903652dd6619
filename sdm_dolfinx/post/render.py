"""Pictures and viewer-friendly files from a run's ``solution.xdmf`` (optional helpers).

Everything here reads the files a run wrote (``solution.xdmf`` + ``.h5``, ``run.json``), so it
works the same for runs made with the command line or the Python API, on any number of ranks
(call it on one rank: Debian's h5py is serial).

* :func:`merge_xdmf` rewrites dolfinx's XDMF, which stores every field as its own temporal
  grid (ParaView then shows four overlapping copies of the mesh, each carrying one array,
  and "Warp By Scalar" + "colour by contact_stress" fails), into one temporal grid whose
  every time step carries all fields. Same HDF5 file, only the XML differs.
* :func:`read_xdmf` loads mesh, times and fields with h5py (no ParaView, no dolfinx).
* :func:`picture` and :func:`animation` render a warped membrane over its obstacle, or a
  deformed elastic body coloured by its von Mises stress, with pyvista off-screen when it is
  installed (``pip install pyvista imageio``; its VTK wheel renders through EGL/OSMesa
  without a display) and with matplotlib otherwise.

Command line::

    python -m sdm_dolfinx.render RUN_DIR [--png F] [--gif F] [--time T] [--merge]

This module imports only the standard library at load time (numpy, h5py, pyvista and
matplotlib inside the functions), so a ParaView ``pvpython`` script can load it by path.
"""
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

#: Xdmf topology name -> (VTK cell type, nodes per cell)
_CELLS = {"Triangle": (5, 3), "Triangle_6": (22, 6), "Quadrilateral": (9, 4), "Tetrahedron": (10, 4)}
#: the four linear triangles of a quadratic (VTK-ordered) triangle, for drawing and gradients
_SUB_TRIANGLES = ((0, 3, 5), (3, 1, 4), (5, 4, 2), (3, 4, 5))
_XI = "http://www.w3.org/2001/XInclude"


def merged_path(xdmf):
    """Where :func:`merge_xdmf` writes by default: ``solution.xdmf`` -> ``solution_paraview.xdmf``."""
    xdmf = Path(xdmf)
    return xdmf.with_name(xdmf.stem + "_paraview.xdmf")


def merge_xdmf(src, dst=None):
    """Write an XDMF file with one temporal grid holding every field at every time.

    dolfinx writes the mesh grid and then one temporal collection per function; ParaView's
    readers turn that into one block per function, each a full copy of the mesh with a single
    array. The file written here references the same HDF5 datasets (so it must stay next to
    ``src``) but lists, per time step, the mesh and all attributes of that time, and declares
    the float data as 8-byte (dolfinx 0.5 leaves Xdmf's 4-byte default, so ParaView reads
    ``solution.xdmf`` in single precision).

    Args:
        src: a ``solution.xdmf`` written by dolfinx.
        dst: the output path (default :func:`merged_path` of ``src``).

    Returns:
        The path written.
    """
    src = Path(src)
    dst = merged_path(src) if dst is None else Path(dst)
    root = ET.parse(src).getroot()
    domain = root.find("Domain")
    mesh = next(g for g in domain.findall("Grid") if g.get("GridType") == "Uniform")
    topology, geometry = mesh.find("Topology"), mesh.find("Geometry")
    times, attributes = [], {}
    for coll in domain.findall("Grid"):
        if coll.get("GridType") != "Collection":
            continue
        for g in coll.findall("Grid"):
            t = g.find("Time").get("Value")
            if t not in attributes:
                times.append(t)
                attributes[t] = []
            attributes[t].extend(g.findall("Attribute"))
    # dolfinx 0.5 omits the precision of its float data, and Xdmf's default is 4 bytes: ParaView
    # then reads the (8-byte) coordinates and fields in single precision. Say 8 (dolfinx writes
    # PETSc's double scalars).
    for item in list(geometry.iter("DataItem")) + [d for t in times for a in attributes[t] for d in a.iter("DataItem")]:
        if "Precision" not in item.attrib and item.get("NumberType", "Float") == "Float":
            item.set("NumberType", "Float")
            item.set("Precision", "8")
    out = ET.Element("Xdmf", {"Version": "3.0"})
    dom = ET.SubElement(out, "Domain")
    series = ET.SubElement(dom, "Grid", {"Name": "solution", "GridType": "Collection",
                                         "CollectionType": "Temporal"})
    for t in sorted(times, key=float):
        g = ET.SubElement(series, "Grid", {"Name": "solution", "GridType": "Uniform"})
        g.append(topology)
        g.append(geometry)
        ET.SubElement(g, "Time", {"Value": t})
        for a in attributes[t]:
            g.append(a)
    ET.indent(out)
    tmp = dst.with_name(dst.name + ".tmp")
    with open(tmp, "wb") as fh:
        fh.write(b'<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n')
        ET.ElementTree(out).write(fh, encoding="utf-8")
        fh.write(b"\n")
    os.replace(tmp, dst)
    return dst


class Series:
    """A run's fields as numpy arrays, read from its XDMF/HDF5 files.

    Attributes:
        points: (n, 3) node coordinates.
        cells: (m, k) node indices per cell, VTK ordering.
        cell_type: the Xdmf topology name (``"Triangle"``, ``"Triangle_6"``, ...).
        times: sorted list of output times.
        run: the run's ``run.json`` (empty dict when there is none).
    """

    def __init__(self, points, cells, cell_type, times, datasets, h5path, run, xdmf=None):
        self.points, self.cells, self.cell_type, self.times = points, cells, cell_type, times
        self.xdmf = xdmf
        self._datasets, self._h5path, self.run = datasets, h5path, run

    @property
    def fields(self):
        """Names of the fields stored at the output times."""
        return sorted(self._datasets)

    def field(self, name, time):
        """The nodal values of ``name`` at the output time nearest to ``time``, shape (n,) or (n, k)."""
        import h5py
        import numpy as np
        k = self.index(time)
        with h5py.File(self._h5path, "r") as h5:
            a = np.array(h5[self._datasets[name][k]])
        return a[:, 0] if a.ndim == 2 and a.shape[1] == 1 else a

    def index(self, time):
        """Index of the output time nearest to ``time``."""
        import numpy as np
        return int(np.argmin(np.abs(np.asarray(self.times) - time)))

    @property
    def parameters(self):
        """The problem's parameters from run.json."""
        return self.run.get("problem", {}).get("parameters", {})

    @property
    def problem_name(self):
        """The problem's name from run.json (``membrane``, ``disc``, ...)."""
        return self.run.get("problem", {}).get("name", "")

    def vertex_mask(self):
        """True at the nodes that are cell vertices (not the midside nodes of quadratic cells)."""
        import numpy as np
        mask = np.zeros(len(self.points), dtype=bool)
        mask[self.cells[:, :3].ravel()] = True
        return mask

    def linear_triangles(self):
        """(m', 3) straight triangles covering the mesh (quadratic ones split in four)."""
        import numpy as np
        if self.cell_type == "Triangle":
            return self.cells
        if self.cell_type == "Triangle_6":
            return np.concatenate([self.cells[:, list(s)] for s in _SUB_TRIANGLES])
        raise ValueError(f"cannot draw {self.cell_type} cells")


def read_xdmf(path):
    """Read a dolfinx ``solution.xdmf`` (or its merged version) into a :class:`Series`.

    Args:
        path: the XDMF file or the run's folder.
    """
    import h5py
    import numpy as np
    path = Path(path)
    if path.is_dir():
        path = path / "solution.xdmf"
    root = ET.parse(path).getroot()
    top = root.find(".//Topology")
    geo = root.find(".//Geometry")
    h5name = top.find("DataItem").text.strip().split(":")[0]
    h5path = path.parent / h5name
    datasets, times = {}, set()
    for g in root.iter("Grid"):
        t = g.find("Time")
        if t is None:
            continue
        times.add(float(t.get("Value")))
        for a in g.findall("Attribute"):
            datasets.setdefault(a.get("Name"), {})[float(t.get("Value"))] = a.find("DataItem").text.strip().split(":")[1]
    times = sorted(times)
    datasets = {k: [v[t] for t in times] for k, v in datasets.items()}
    with h5py.File(h5path, "r") as h5:
        x = np.array(h5[geo.find("DataItem").text.strip().split(":")[1]])
        cells = np.array(h5[top.find("DataItem").text.strip().split(":")[1]], dtype=np.int64)
    points = np.zeros((x.shape[0], 3))
    points[:, :x.shape[1]] = x
    run_json = path.parent / "run.json"
    run = json.loads(run_json.read_text()) if run_json.exists() else {}
    return Series(points, cells, top.get("TopologyType"), times, datasets, h5path, run, path.resolve())


def von_mises(series, displacement, lame_lambda, lame_mu):
    """Plane-strain von Mises stress of a vertex displacement, one value per linear triangle.

    The displacement is piecewise linear on :meth:`Series.linear_triangles`, so the strain is
    constant on each of them; sigma_zz = lambda tr(eps) (plane strain).
    """
    import numpy as np
    tri = series.linear_triangles()
    x = series.points[:, :2][tri]                 # (m, 3, 2)
    u = displacement[:, :2][tri]
    d = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=1)       # rows: edge vectors
    du = np.stack([u[:, 1] - u[:, 0], u[:, 2] - u[:, 0]], axis=1)
    grad = np.linalg.solve(d, du).transpose(0, 2, 1)                     # grad[i, j] = du_i/dx_j
    eps = 0.5 * (grad + grad.transpose(0, 2, 1))
    tr = eps[:, 0, 0] + eps[:, 1, 1]
    sxx = lame_lambda * tr + 2 * lame_mu * eps[:, 0, 0]
    syy = lame_lambda * tr + 2 * lame_mu * eps[:, 1, 1]
    sxy = 2 * lame_mu * eps[:, 0, 1]
    szz = lame_lambda * tr
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3 * sxy ** 2)


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


def _run_child(args):
    cmd = [sys.executable, "-P", str(Path(__file__).resolve())] + [str(a) for a in args]
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
    """The rigid support: the line y = 0 (disc) or x = 0 (bar), as a hatched-grey band."""
    import numpy as np
    pv = _pv_setup()
    p = series.points
    span = np.ptp(p[:, :2], axis=0).max()
    if name == "bar":
        box = pv.Box(bounds=(-0.05 * span, 0.0, p[:, 1].min() - 0.3 * np.ptp(p[:, 1]),
                             p[:, 1].max() + 0.3 * np.ptp(p[:, 1]), -0.01, 0.0))
    else:
        x0, x1 = p[:, 0].min(), p[:, 0].max()
        box = pv.Box(bounds=(x0 - 0.1 * span, x1 + 0.1 * span, -0.05 * span, 0.0, -0.01, 0.0))
    plotter.add_mesh(box, color="#9a9a9a", name="foundation")


def _lame(series):
    p = series.parameters
    return float(p.get("lame_lambda", 0.0)), float(p.get("lame_mu", 1.0))


def _stress_range(series, times, lame):
    import numpy as np
    top = max(float(np.max(von_mises(series, series.field("displacement", t), *lame))) for t in times)
    return [0.0, top if top > 0 else 1.0]


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
        _picture_mpl(series, png, t, scale, kind)
        return "matplotlib"
    if _in_child():
        return _run_child([series.xdmf, "--png", Path(png).resolve(), "--time", repr(t), "--scale", repr(scale),
                           "--size", size[0], size[1]])
    pv = _pv_setup()
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    plotter.set_background("white")
    if kind == "membrane":
        u = series.field("displacement", t)
        _membrane_frame_pv(plotter, series, t, scale, [0.0, max(u.max(), 1e-12)])
        _membrane_camera(plotter, series, scale)
    else:
        lame = _lame(series)
        _foundation_pv(plotter, series, series.problem_name)
        _solid_frame_pv(plotter, series, t, scale, _stress_range(series, [t], lame), lame)
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
        _animation_mpl(series, path, times, scale, kind, fps)
        return "matplotlib"
    if _in_child():
        return _run_child([series.xdmf, "--gif", Path(path).resolve(), "--times", json.dumps(times),
                           "--scale", repr(scale), "--size", size[0], size[1], "--fps", fps])
    import imageio.v2 as imageio
    pv = _pv_setup()
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    plotter.set_background("white")
    if kind == "membrane":
        top = max(float(series.field("displacement", t).max()) for t in times)
        clim = [0.0, top]
    else:
        lame = _lame(series)
        clim = _stress_range(series, times, lame)
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


# ------------------------------------------------------------------------ matplotlib: the disc mesh
def p2_edge_lines(xy, samples=9):
    """Polylines of the curved edges of quadratic triangles, for a matplotlib LineCollection.

    ``xy``: (ncells, 6, 2) node coordinates in dolfinx's P2 order (vertices 0-2, then the
    midpoint of edge v1-v2, v0-v2, v0-v1); returns (3 ncells, samples, 2).
    """
    import numpy as np
    s = np.linspace(0.0, 1.0, samples)[:, None]
    lines = []
    for a, m, b in ((1, 3, 2), (0, 4, 2), (0, 5, 1)):
        pa, pm, pb = xy[:, a, None, :], xy[:, m, None, :], xy[:, b, None, :]
        lines.append((1 - s) * (1 - 2 * s) * pa + 4 * s * (1 - s) * pm + s * (2 * s - 1) * pb)
    return np.concatenate(lines)


def draw_foundation(ax, x0, x1):
    """The rigid foundation y <= 0 (hatched) between x0 and x1 (mm)."""
    ax.axhline(0.0, color="k", lw=1.5)
    ax.fill_between([x0, x1], [-2.0, -2.0], [0.0, 0.0], color="0.85", hatch="///", lw=0)


def draw_disc_mesh(ax, xy, contact, title):
    """The disc's curved P2 mesh, its contact vertices (``contact``: (n, 2)), the foundation
    and the lowest point A, on a matplotlib axes (the paper's Fig. 13)."""
    import numpy as np
    from matplotlib.collections import LineCollection
    ax.add_collection(LineCollection(p2_edge_lines(xy), colors="k", linewidths=0.6))
    ax.plot(contact[:, 0], contact[:, 1], "o", color="tab:red", ms=3.5, label=f"contact vertices ({len(contact)})")
    a = contact[np.argmin(contact[:, 1])]
    ax.annotate("A", a, xytext=(a[0] + 1.5, a[1] - 2.5), fontsize=12)
    draw_foundation(ax, -22, 22)
    ax.set_xlim(-22, 22)
    ax.set_ylim(-2, 52)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title)


# ------------------------------------------------------------------------ matplotlib fallback
def _mpl():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _mpl_draw(fig, series, t, scale, kind, clim=None):
    import matplotlib.tri as mtri
    import numpy as np
    tri = series.linear_triangles()
    u = series.field("displacement", t)
    fig.clear()
    if kind == "membrane":
        ax = fig.add_subplot(projection="3d")
        x, y = series.points[:, 0], series.points[:, 1]
        tr = mtri.Triangulation(x, y, tri)
        obstacle = float(series.parameters.get("obstacle", 0.0))
        xx, yy = np.meshgrid([x.min(), x.max()], [y.min(), y.max()])
        ax.plot_surface(xx, yy, np.full_like(xx, scale * obstacle), color="0.7", alpha=0.6)
        surf = ax.plot_trisurf(tr, scale * u, cmap="viridis", linewidth=0.2, edgecolor="0.3",
                               vmin=None if clim is None else clim[0], vmax=None if clim is None else clim[1] * scale)
        act = series.field("active", t) > 0.5
        ax.scatter(x[act], y[act], scale * u[act], color="red", s=12)
        ax.set_zlim(min(scale * obstacle, scale * u.min()) - 0.02, max(scale * u.max(), 0.1))
        ax.set_title(f"t = {series.times[series.index(t)]:.3f} (vertical scale x{scale:g}; red: in contact)")
        fig.colorbar(surf, ax=ax, shrink=0.6, label=f"{scale:g} x displacement")
    else:
        ax = fig.add_subplot()
        xy = series.points[:, :2] + scale * u[:, :2]
        vm = von_mises(series, u, *_lame(series))
        pc = ax.tripcolor(xy[:, 0], xy[:, 1], tri, facecolors=vm, cmap="inferno",
                          vmin=0 if clim is None else clim[0], vmax=None if clim is None else clim[1])
        ax.axhline(0.0, color="k") if series.problem_name != "bar" else ax.axvline(0.0, color="k")
        ax.set_aspect("equal")
        ax.set_title(f"t = {series.times[series.index(t)]:.4g}")
        fig.colorbar(pc, ax=ax, label="von Mises stress")
    return ax


def _picture_mpl(series, png, t, scale, kind):
    plt = _mpl()
    fig = plt.figure(figsize=(8, 6))
    _mpl_draw(fig, series, t, scale, kind)
    fig.savefig(png, dpi=100)
    plt.close(fig)


def _animation_mpl(series, path, times, scale, kind, fps):
    from matplotlib.animation import FuncAnimation, PillowWriter
    plt = _mpl()
    fig = plt.figure(figsize=(6.4, 6.4))
    clim = None
    if kind != "membrane":
        clim = _stress_range(series, times, _lame(series))
    anim = FuncAnimation(fig, lambda i: _mpl_draw(fig, series, times[i], scale, kind, clim), frames=len(times))
    anim.save(str(path), writer=PillowWriter(fps=fps))
    plt.close(fig)


def main(argv=None):
    """``python -m sdm_dolfinx.render RUN_DIR [--png F] [--gif F] [--time T] [--merge]``."""
    import argparse
    p = argparse.ArgumentParser(prog="python -m sdm_dolfinx.render",
                                description="Pictures of a run from its solution.xdmf (pyvista if installed, "
                                            "else matplotlib), and a ParaView-friendly merged XDMF.")
    p.add_argument("run", type=Path, help="the run's folder (or its solution.xdmf)")
    p.add_argument("--png", type=Path, help="write a picture at --time (default: the last output time)")
    p.add_argument("--gif", type=Path, help="write an animation of all output times (.gif, or .mp4)")
    p.add_argument("--time", type=float, default=None, help="time of the picture (nearest output time)")
    p.add_argument("--scale", type=float, default=None,
                   help="displacement magnification (default 10 for the membrane, 1 for elastic bodies)")
    p.add_argument("--every", type=int, default=1, metavar="K", help="animation: every K-th output time")
    p.add_argument("--times", type=json.loads, default=None, help=argparse.SUPPRESS)
    p.add_argument("--size", type=int, nargs=2, default=None, metavar=("W", "H"), help="picture size in pixels")
    p.add_argument("--fps", type=float, default=12, help="animation frames per second (default 12)")
    p.add_argument("--merge", action="store_true",
                   help="write solution_paraview.xdmf: all fields in one temporal grid (for ParaView)")
    args = p.parse_args(argv)
    xdmf = args.run / "solution.xdmf" if args.run.is_dir() else args.run
    if args.merge:
        print(f"wrote {merge_xdmf(xdmf)}")
    if args.png or args.gif:
        series = read_xdmf(xdmf)
        if args.png:
            how = picture(series, args.png, time=args.time, scale=args.scale, size=args.size or (900, 700))
            print(f"wrote {args.png} ({how})")
        if args.gif:
            how = animation(series, args.gif, times=args.times or series.times[::args.every], scale=args.scale,
                            size=args.size or (640, 640), fps=args.fps)
            print(f"wrote {args.gif} ({how})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
