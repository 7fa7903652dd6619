"""Render one 3-D picture of the report with pyvista, in a process of its own.

    python -m pyvista_scene SCENE.npz PICTURE.png      (run by :mod:`sdm_dolfinx.study.pictures`)

VTK's pip wheel aborts (std::regex inside vtkScalarBarActor) in a process that has loaded
dolfinx's C++ libraries, and an abort cannot be caught: this module therefore imports only
numpy and pyvista, sees only the numpy arrays of ``SCENE.npz``, and is started with this
folder on ``PYTHONPATH`` (not as ``sdm_dolfinx.study.pyvista_scene``, whose parent package
would load dolfinx first).

``SCENE.npz`` holds ``kind`` (``membrane``, ``disc`` or ``ball``), ``title`` and the VTK grid
(``topology``, ``types``, ``points``); for the membrane the vertex displacement ``u``, its
vertical ``scale`` and the ``contact`` points; for the disc the displacement ``disp``, the
per-cell von Mises stress ``vm`` and the extrusion ``depth``; for the ball ``disp``, ``vm``, its
``radius``, Hertz's contact radius ``a``, the ``depth`` of his largest von Mises stress and the
colour bar's ``vm_label``.
"""
import sys

import numpy as np


def membrane(p, pv, d, grid):
    """The membrane warped by u (scaled), over the obstacle plane, contact vertices in red."""
    grid.point_data["u"] = d["u"]
    warped = grid.warp_by_scalar("u", factor=float(d["scale"]))
    p.add_mesh(warped, scalars="u", cmap="viridis", show_edges=True, edge_color="black",
               scalar_bar_args={"title": "u", "color": "black"})
    obst = pv.Plane(center=(0.5, 0.5, -1e-3), i_size=1.3, j_size=1.3)
    p.add_mesh(obst, color="lightgrey", opacity=0.7)
    pts = d["contact"]
    if len(pts):
        p.add_mesh(pv.PolyData(pts), color="red", point_size=9, render_points_as_spheres=True)
    p.camera_position = [(2.3, -1.5, 1.1), (0.5, 0.5, 0.02), (0, 0, 1)]


def disc(p, pv, d, grid):
    """The deformed disc extruded into a plane-strain cylinder, coloured by von Mises, on its foundation."""
    depth = float(d["depth"])
    grid.point_data["u"] = d["disp"]
    grid.cell_data["von Mises"] = d["vm"]
    grid = grid.cell_data_to_point_data()
    surf = grid.warp_by_vector("u").extract_surface(nonlinear_subdivision=3)
    solid = surf.extrude((0.0, 0.0, depth), capping=True)
    p.add_mesh(solid, scalars="von Mises", cmap="viridis",
               scalar_bar_args={"title": "von Mises (N/mm^2)", "color": "black"})
    p.add_mesh(pv.Box((-30.0, 30.0, -3.0, 0.0, -8.0, depth + 8.0)), color="lightgrey")
    p.camera_position = [(62.0, 42.0, 85.0), (0.0, 14.0, depth / 2), (0.0, 1.0, 0.0)]


def ball(p, pv, d, grid):
    """The deformed ball cut by the plane y = 0 (the half y <= 0, seen from +y), coloured by von Mises:
    the whole ball on the plane z = 0 (left) and a close-up of the contact zone (right) with Hertz's
    contact disc (red, radius a) and the depth of his largest von Mises stress (black dot)."""
    R, a, depth = float(d["radius"]), float(d["a"]), float(d["depth"])
    grid.point_data["u"] = d["disp"]
    grid.cell_data["vm"] = d["vm"]
    warped = grid.cell_data_to_point_data().warp_by_vector("u")
    half = warped.clip(normal=(0.0, 1.0, 0.0), origin=(0.0, 0.0, 0.0), invert=True)
    vmax = float(np.max(d["vm"]))
    bar = {"title": str(d["vm_label"]), "color": "black", "vertical": False, "width": 0.7, "height": 0.09,
           "position_x": 0.15, "position_y": 0.015, "title_font_size": 18, "label_font_size": 16, "n_labels": 6,
           "fmt": "%.2f"}
    # left: the whole ball; right: a window 6 a wide around the contact
    p.subplot(0, 0)
    p.set_background("white")
    p.add_mesh(half, scalars="vm", cmap="viridis", clim=(0.0, vmax), scalar_bar_args=bar)
    p.add_mesh(pv.Box((-1.3 * R, 1.3 * R, -1.3 * R, 0.0, -0.05 * R, 0.0)), color="lightgrey")
    p.camera_position = [(0.0, 5.9 * R, 1.0 * R), (0.0, 0.0, 0.95 * R), (0.0, 0.0, 1.0)]
    p.add_text("whole ball (R = %g mm) on the rigid plane z = 0" % R, position=(10, 640), font_size=11,
               color="black")
    p.subplot(0, 1)
    p.set_background("white")
    p.add_mesh(half, scalars="vm", cmap="viridis", clim=(0.0, vmax), show_scalar_bar=False, show_edges=True,
               edge_color="#d0d0d0", line_width=0.3, edge_opacity=0.35)
    p.add_mesh(pv.Box((-6.0 * a, 6.0 * a, -6.0 * a, 0.0, -1.5 * a, 0.0)), color="lightgrey")
    p.add_mesh(pv.Line((-a, 0.05 * a, 0.0), (a, 0.05 * a, 0.0)), color="red", line_width=7,
               label="Hertz's contact disc, radius a = %.2f mm" % a)
    p.add_mesh(pv.PolyData(np.array([[0.0, 0.1 * a, depth]])), color="black", point_size=16,
               render_points_as_spheres=True, label="Hertz's largest von Mises stress: depth 0.48 a")
    p.add_legend(bcolor="white", face=None, size=(0.75, 0.12), loc="lower left")
    p.enable_parallel_projection()
    p.camera_position = [(0.0, 50.0 * a, 1.5 * a), (0.0, 0.0, 1.5 * a), (0.0, 0.0, 1.0)]
    p.camera.parallel_scale = 2.6 * a
    p.add_text("close-up of the contact zone (a = %.2f mm; cell edges of the cut in grey)" % a,
               position=(10, 720), font_size=11, color="white")


def main(argv):
    """Render the scene file ``argv[0]`` into the PNG ``argv[1]``."""
    import pyvista as pv
    pv.OFF_SCREEN = True
    d = np.load(argv[0])
    kind, title = str(d["kind"]), str(d["title"])
    grid = pv.UnstructuredGrid(d["topology"], d["types"], d["points"])
    if kind == "ball":
        p = pv.Plotter(off_screen=True, window_size=(1600, 760), shape=(1, 2), border=False)
        ball(p, pv, d, grid)
        p.subplot(0, 0)
        p.add_text(title, position=(10, 695), font_size=10, color="black")
    else:
        p = pv.Plotter(off_screen=True, window_size=(1100, 750))
        p.set_background("white")
        (membrane if kind == "membrane" else disc)(p, pv, d, grid)
        p.add_text(title, font_size=9, color="black")
    p.screenshot(argv[1])
    p.close()


if __name__ == "__main__":
    main(sys.argv[1:])
