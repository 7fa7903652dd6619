"""Render one 3-D picture of the report with pyvista, in a process of its own.

    python -m pyvista_scene SCENE.npz PICTURE.png      (run by :mod:`sdm_dolfinx.paper.pictures`)

VTK's pip wheel aborts (std::regex inside vtkScalarBarActor) in a process that has loaded
dolfinx's C++ libraries, and an abort cannot be caught: this module therefore imports only
numpy and pyvista, sees only the numpy arrays of ``SCENE.npz``, and is started with this
folder on ``PYTHONPATH`` (not as ``sdm_dolfinx.paper.pyvista_scene``, whose parent package
would load dolfinx first).

``SCENE.npz`` holds ``kind`` (``membrane`` or ``disc``), ``title`` and the VTK grid
(``topology``, ``types``, ``points``); for the membrane the vertex displacement ``u``, its
vertical ``scale`` and the ``contact`` points; for the disc the displacement ``disp``, the
per-cell von Mises stress ``vm`` and the extrusion ``depth``.
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


def main(argv):
    """Render the scene file ``argv[0]`` into the PNG ``argv[1]``."""
    import pyvista as pv
    pv.OFF_SCREEN = True
    d = np.load(argv[0])
    kind, title = str(d["kind"]), str(d["title"])
    grid = pv.UnstructuredGrid(d["topology"], d["types"], d["points"])
    p = pv.Plotter(off_screen=True, window_size=(1100, 750))
    p.set_background("white")
    (membrane if kind == "membrane" else disc)(p, pv, d, grid)
    p.add_text(title, font_size=9, color="black")
    p.screenshot(argv[1])
    p.close()


if __name__ == "__main__":
    main(sys.argv[1:])
