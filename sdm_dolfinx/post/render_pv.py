"""The pyvista drawings of :mod:`.render`: a membrane warped over its obstacle, a 2-D body or a 3-D
body's surface deformed and coloured, each with the obstacle its problem declares.

Imports only the standard library at load time (numpy and pyvista inside the functions): it runs
in the child process of :mod:`.render`, loaded by path, and takes a
:class:`~sdm_dolfinx.io.xdmf_reader.Series`, the obstacle (:mod:`.render_obstacle`'s plain data)
and a ``look`` (:class:`sdm_dolfinx.post.render.Look`: the colour, its title with its unit, the
picture's title).
"""
import os

GREY = "#9a9a9a"
#: the edges' colours of the bodies of a run with ``bodies`` (1, 2, ...), bright against the inferno map
BODY_COLOURS = ("#1f77b4", "#2ca02c", "#17becf", "#e377c2", "#bcbd22", "#7f7fff")


def setup():
    """pyvista, off screen (EGL without a display)."""
    import pyvista as pv
    pv.OFF_SCREEN = True
    # a VTK wheel tries X first and warns when there is none; go straight to EGL then
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    # the mesh's edges lie on its surface: push the surface back a little so that they are not
    # dashed by the depth test
    from vtkmodules.vtkRenderingCore import vtkMapper
    vtkMapper.SetResolveCoincidentTopologyToPolygonOffset()
    vtkMapper.SetResolveCoincidentTopologyPolygonOffsetParameters(2.0, 4.0)
    return pv


def _grid(series, points=None):
    """The straight triangles that draw the mesh (or the 3-D body's surface) as a PolyData."""
    import numpy as np
    pv = setup()
    tri = series.surface_triangles()
    faces = np.hstack([np.full((len(tri), 1), 3), tri]).ravel()
    return pv.PolyData(series.points.copy() if points is None else points, faces=faces)


def _text(plotter, text, font, panels=1, **kwargs):
    """``text`` in black, wrapped at spaces to the panel's width (VTK drops a corner text that does
    not fit rather than cutting it)."""
    import textwrap
    width = max(20, int(plotter.window_size[0] / panels / (0.62 * font)))
    lines = textwrap.wrap(text, width, break_long_words=False)
    plotter.add_text("\n".join(lines), font_size=font, color="black", **kwargs)


def _bar(look, font, **where):
    return {"title": look.colour_title + "\n", "vertical": True, "fmt": "%.3g", "color": "black",
            "title_font_size": font, "label_font_size": font - 2, "n_labels": 5, **where}


def _active(plotter, series, t, points, colour, size):
    """The vertices in contact (midside nodes carry interpolated flags: left out); returns their number."""
    import numpy as np
    pv = setup()
    active = (series.field("active", t) > 0.5) & series.vertex_mask()
    if active.any():
        plotter.add_mesh(pv.PolyData(points[active]), color=colour, point_size=size, render_points_as_spheres=True,
                         name="active")
    else:
        plotter.remove_actor("active")
    return int(np.sum(active))


def _obstacle_surface(points, axes):
    """A PolyData through obstacle points, triangulated over the two coordinates ``axes``."""
    import numpy as np
    from matplotlib.tri import Triangulation
    pv = setup()
    p = np.asarray(points, dtype=float)
    tri = Triangulation(p[:, axes[0]], p[:, axes[1]]).triangles
    return pv.PolyData(p, faces=np.hstack([np.full((len(tri), 1), 3), tri]).ravel())


# ------------------------------------------------------------------------ the membrane
def membrane_frame(plotter, series, t, scale, clim, look, obstacle):
    """The membrane warped by u (times ``scale``) over its obstacle, vertices in contact in red."""
    import numpy as np
    pv = setup()
    u = series.field("displacement", t)
    grid = _grid(series)
    grid.points[:, 2] = scale * u
    grid.point_data["displacement"] = u
    x0, x1 = series.points[:, 0].min(), series.points[:, 0].max()
    y0, y1 = series.points[:, 1].min(), series.points[:, 1].max()
    # the obstacle drawn a hair below its height, so that the membrane lying on it stays visible
    lift = 2e-3 * max(x1 - x0, y1 - y0)
    if obstacle.get("flat") is not None:
        plotter.add_mesh(pv.Plane(center=((x0 + x1) / 2, (y0 + y1) / 2, scale * obstacle["flat"] - lift),
                                  direction=(0, 0, 1), i_size=1.3 * (x1 - x0), j_size=1.3 * (y1 - y0)),
                         color="#8c8c8c", name="obstacle")
    elif obstacle.get("points"):
        surface = _obstacle_surface(obstacle["points"], (0, 1))
        surface.points[:, 2] = scale * surface.points[:, 2] - lift
        plotter.add_mesh(surface, color="#8c8c8c", name="obstacle")
    plotter.add_mesh(grid, scalars="displacement", cmap="viridis", clim=clim, show_edges=True,
                     edge_color="#404040", line_width=0.5, name="membrane",
                     scalar_bar_args=_bar(look, 16, position_x=0.87, position_y=0.25))
    n = _active(plotter, series, t, grid.points + [0.0, 0.0, lift], "red", 10)
    _text(plotter, look.title(t, n, "red"), 11, name="title")


def membrane_camera(plotter, series):
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


# ------------------------------------------------------------------------ bodies in 2-D and 3-D
def solid_frame(plotter, series, t, scale, clim, look, bar=True, title=True):
    """A 2-D body or a 3-D body's surface, deformed (times ``scale``), coloured by ``look.values``."""
    u = series.field("displacement", t)
    d = series.gdim
    points = series.points.copy()
    points[:, :d] += scale * u[:, :d]
    grid = _grid(series, points)
    grid.point_data["colour"] = look.values(u)
    w, h = plotter.window_size
    font = max(10, round(16 * min(w / 900, h / 700)))       # smaller in a small animation frame
    plotter.add_mesh(grid, scalars="colour", cmap="inferno", clim=clim, name="body", show_scalar_bar=bar,
                     scalar_bar_args=_bar(look, font, position_x=0.83, position_y=0.2, width=0.08, height=0.6))
    segments = _edges(series)
    bodies = series.node_bodies(t)
    if bodies is None:
        plotter.add_mesh(_lines(points, segments), color="white", opacity=0.35, line_width=0.6, name="edges")
    else:                       # each body's edges in its colour, named in a legend
        tag, names = bodies
        for k, name in enumerate(names, start=1):
            mine = segments[tag[segments[:, 0]] == k]
            if len(mine):
                plotter.add_mesh(_lines(points, mine), color=BODY_COLOURS[(k - 1) % len(BODY_COLOURS)],
                                 line_width=1.2, name=f"edges_{k}")
        if bar:
            plotter.add_legend([[f"edges: {name}", BODY_COLOURS[k % len(BODY_COLOURS)]] for k, name in enumerate(names)],
                               bcolor="white", size=(0.22, 0.05 * len(names)), loc="lower left")
    n = _active(plotter, series, t, points, "cyan", 9)
    if title:
        _text(plotter, look.title(t, n, "cyan"), 11 if d == 2 else 10, panels=d - 1, name="title")


def _lines(points, segments):
    """The segments (pairs of node numbers) as a PolyData of lines."""
    import numpy as np
    pv = setup()
    return pv.PolyData(points, lines=np.hstack([np.full((len(segments), 1), 2), segments]).ravel())


def _edges(series):
    """The cell edges drawn, as pairs of node numbers: the triangles' (2-D) or the surface faces' (3-D),
    straight between corners, through the mid-edge node of quadratic ones."""
    import numpy as np
    faces = series.boundary_faces() if series.tdim == 3 else series.cells
    if faces.shape[1] == 3:
        segments = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    else:                                 # corners, then the mid-edge nodes of 01, 12, 20
        segments = np.concatenate([faces[:, [a, m]] for a, b, m in ((0, 1, 3), (1, 2, 4), (2, 0, 5))]
                                  + [faces[:, [m, b]] for a, b, m in ((0, 1, 3), (1, 2, 4), (2, 0, 5))])
    return np.unique(np.sort(segments, axis=1), axis=0)


def extent(series, times, scale):
    """(lo, hi): the box holding the deformed body over ``times`` (gdim coordinates)."""
    import numpy as np
    d = series.gdim
    p = series.points[:, :d]
    lo = np.min([p + scale * series.field("displacement", t)[:, :d] for t in times], axis=(0, 1))
    hi = np.max([p + scale * series.field("displacement", t)[:, :d] for t in times], axis=(0, 1))
    return lo, hi


def obstacle_2d(plotter, obstacle, lo, hi):
    """A flat obstacle x_c = value as a grey band on its far side, or a grey line through its points;
    returns (lo, hi) grown to hold it."""
    import numpy as np
    pv = setup()
    c, span = obstacle.get("component"), float(np.max(hi - lo))
    if c is None or not obstacle.get("points"):
        return lo, hi
    o = 1 - c                                             # the other axis
    if obstacle["flat"] is not None:
        v = obstacle["flat"]
        a0, a1 = lo[o] - 0.1 * span, hi[o] + 0.1 * span
        box = [0.0] * 6
        box[2 * c:2 * c + 2], box[2 * o:2 * o + 2], box[4:] = (v - 0.05 * span, v), (a0, a1), (-0.01, 0.0)
        plotter.add_mesh(pv.Box(bounds=box), color=GREY, name="obstacle")
        lo, hi = lo.copy(), hi.copy()
        lo[c], hi[c] = min(lo[c], v - 0.05 * span), max(hi[c], v)
        lo[o], hi[o] = min(lo[o], a0), max(hi[o], a1)
        return lo, hi
    p = np.asarray(obstacle["points"], dtype=float)
    p = p[np.argsort(p[:, o])]
    plotter.add_mesh(pv.lines_from_points(p), color=GREY, line_width=5, name="obstacle")
    return np.minimum(lo, p[:, :2].min(axis=0)), np.maximum(hi, p[:, :2].max(axis=0))


def shapes_2d(plotter, look, t, lo=None, hi=None):
    """The obstacles' outlines at the time ``t`` as grey lines (the same actor replaced at every frame);
    returns (lo, hi) grown to hold them at every time drawn (None: not asked)."""
    import numpy as np
    pv = setup()
    points, cells = look.obstacle_shape(t)
    if len(cells):
        lines = np.hstack([np.full((len(cells), 1), 2), cells]).ravel()
        plotter.add_mesh(pv.PolyData(points, lines=lines), color=GREY, line_width=5, name="obstacle")
    else:
        plotter.remove_actor("obstacle")
    every = np.concatenate([np.asarray(s["points"], dtype=float).reshape(-1, 3) for s in look.obstacle["shapes"]])
    if len(every) and lo is not None:
        lo, hi = np.minimum(lo, every[:, :2].min(axis=0)), np.maximum(hi, every[:, :2].max(axis=0))
    return lo, hi


def shapes_3d(plotter, look, t):
    """The obstacles' surfaces at the time ``t``, grey and translucent (again at every frame when they move)."""
    import numpy as np
    pv = setup()
    points, cells = look.obstacle_shape(t)
    if len(cells):
        faces = np.hstack([np.full((len(cells), 1), 3), cells]).ravel()
        plotter.add_mesh(pv.PolyData(points, faces=faces), color=GREY, opacity=0.55, name="obstacle")
    else:
        plotter.remove_actor("obstacle")


def view_2d(plotter, lo, hi):
    """A fixed camera framing the box (lo, hi) with headroom for the title and the colour bar."""
    import numpy as np
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


def obstacle_3d(plotter, obstacle, lo, hi):
    """A flat obstacle x_c = value as a thin grey slab under the body (1.4 times its width), or a
    grey surface through its points."""
    import numpy as np
    pv = setup()
    c = obstacle.get("component")
    if c is None or not obstacle.get("points"):
        return
    if obstacle["flat"] is not None:
        v, size, mid = obstacle["flat"], float(np.max(hi - lo)), 0.5 * (lo + hi)
        box = []
        for k in range(3):
            box += [v - 0.02 * size, v] if k == c else [mid[k] - 0.7 * (hi[k] - lo[k]), mid[k] + 0.7 * (hi[k] - lo[k])]
        plotter.add_mesh(pv.Box(bounds=box), color=GREY, opacity=0.55, name="obstacle")
    else:
        plotter.add_mesh(_obstacle_surface(obstacle["points"], [k for k in range(3) if k != c]), color=GREY,
                         opacity=0.55, name="obstacle")


def _camera_3d(plotter, obstacle, lo, hi, elevation, azimuth=-60.0, zoom=1.1):
    """A perspective view ``elevation`` degrees above the obstacle's plane (its normal up; z up
    without one); -90: from under the obstacle, along its normal."""
    import numpy as np
    up = obstacle.get("component")
    up = 2 if up is None else up
    h1, h2 = [k for k in range(3) if k != up]
    el, az = np.radians(elevation), np.radians(azimuth)
    direction = np.zeros(3)
    direction[h1], direction[h2], direction[up] = np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)
    view_up = np.eye(3)[up] if abs(elevation) < 89 else np.eye(3)[h2]
    centre, size = 0.5 * (lo + hi), float(np.linalg.norm(hi - lo))
    plotter.camera_position = [tuple(centre + 3.0 * size * direction), tuple(centre), tuple(view_up)]
    plotter.reset_camera()
    plotter.camera.zoom(zoom)


def _contact_zone(series, times, scale):
    """(centre, radius) of the deformed vertices in contact over ``times``, or None without contact."""
    import numpy as np
    pts = []
    for t in times:
        active = (series.field("active", t) > 0.5) & series.vertex_mask()
        pts.append(series.points[active] + scale * series.field("displacement", t)[active])
    pts = np.concatenate(pts)
    if not len(pts):
        return None
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    return centre, float(np.max(np.linalg.norm(pts - centre, axis=1)))


def solid3d_frame(plotter, series, times, frame, scale, clim, look, obstacle):
    """Two views of a 3-D body: from the side, 15 degrees above the obstacle (left, with the
    title and the colour bar), and from under the obstacle along its normal, the obstacle left
    out (right: a close-up of the vertices in contact over ``times``, or the whole body without)."""
    if frame == 0:
        lo, hi = extent(series, times, scale)
        zone = _contact_zone(series, times, scale)
    for panel in (0, 1):
        plotter.subplot(0, panel)
        if frame == 0:
            plotter.set_background("white")
            if panel == 0:
                obstacle_3d(plotter, obstacle, lo, hi)
        if panel == 0 and obstacle.get("shapes") and (frame == 0 or obstacle.get("moving")):
            shapes_3d(plotter, look, times[frame])
        solid_frame(plotter, series, times[frame], scale, clim, look, bar=panel == 0, title=panel == 0)
        if frame == 0 and panel == 0:
            _camera_3d(plotter, obstacle, lo, hi, 15.0, zoom=0.9)        # room for the colour bar
        elif frame == 0:
            below = "under the obstacle" if obstacle.get("points") and obstacle.get("component") is not None \
                else "below"
            if zone is None:
                _camera_3d(plotter, obstacle, lo, hi, -90.0)
                text = f"right: the body seen from {below} (no vertex in contact)"
            else:
                centre, radius = zone
                size = float(max(hi - lo))
                radius = min(max(4.0 * radius, 0.1 * size), 0.6 * size)
                _camera_3d(plotter, obstacle, centre - radius, centre + radius, -90.0)
                plotter.enable_parallel_projection()
                plotter.camera.parallel_scale = 1.2 * radius
                text = f"right: the vertices in contact seen from {below} (a window {2.4 * radius:.3g}{look.length} wide)"
            plotter.subplot(0, 0)
            _text(plotter, text, 10, panels=2, position="lower_left")


def draw(plotter, series, times, scale, clim, look, obstacle, frame):
    """Draw frame ``frame`` of ``times`` (the obstacle and the camera with the first one)."""
    t = times[frame]
    if look.kind == "membrane":
        membrane_frame(plotter, series, t, scale, clim, look, obstacle)
        if frame == 0:
            membrane_camera(plotter, series)
    elif look.kind == "solid3d":
        solid3d_frame(plotter, series, times, frame, scale, clim, look, obstacle)
    else:
        if frame == 0:
            lo, hi = obstacle_2d(plotter, obstacle, *extent(series, times, scale))
            if obstacle.get("shapes"):
                lo, hi = shapes_2d(plotter, look, t, lo, hi)
        elif obstacle.get("shapes") and obstacle.get("moving"):
            shapes_2d(plotter, look, t)
        solid_frame(plotter, series, t, scale, clim, look)
        if frame == 0:
            view_2d(plotter, lo, hi)


def _plotter(look, size):
    pv = setup()
    if look.kind == "solid3d":
        plotter = pv.Plotter(off_screen=True, window_size=list(size), shape=(1, 2), border=False)
    else:
        plotter = pv.Plotter(off_screen=True, window_size=list(size))
        plotter.set_background("white")
    return plotter


def picture(series, png, t, scale, clim, look, obstacle, size):
    """A PNG of one time."""
    plotter = _plotter(look, size)
    draw(plotter, series, [t], scale, clim, look, obstacle, 0)
    plotter.screenshot(str(png))
    plotter.close()


def animation(series, path, times, scale, clim, look, obstacle, size, fps):
    """A GIF (or MP4) of ``times``, with one colour scale and one camera for every frame."""
    import imageio.v2 as imageio
    plotter = _plotter(look, size)
    frames = []
    for i in range(len(times)):
        draw(plotter, series, times, scale, clim, look, obstacle, i)
        plotter.render()
        frames.append(plotter.screenshot(return_img=True))
    plotter.close()
    if str(path).lower().endswith(".mp4"):
        imageio.mimsave(str(path), frames, fps=fps)
    else:
        imageio.mimsave(str(path), frames, duration=1000.0 / fps, loop=0)
