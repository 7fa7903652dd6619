"""Open a run's XDMF output with ParaView's own reader and check what a user would see.

Run with ParaView's Python (Debian: ``apt-get install paraview``)::

    pvpython scripts/paraview_check.py RUN_DIR [--json SUMMARY.json] [--png PICTURE.png]
    xvfb-run -a -s "-screen 0 1280x1024x24 -noreset" pvpython scripts/paraview_check.py RUN_DIR --png out.png    # rendering needs a display

It loads ``RUN_DIR/solution.xdmf`` with ``Xdmf3ReaderS`` (ParaView's "XDMF Reader"), steps
through every time step and checks, at each: the arrays ``displacement``, ``velocity``,
``contact_stress`` and ``active`` are there, one value (or 3-vector) per mesh node, finite;
``active`` lies in [0, 1] (exactly 0 or 1 at vertices; midside nodes of quadratic meshes
carry averages); ``contact_stress`` >= 0 (compressive) and nonzero only where ``active`` is;
times start at 0 and increase; a 2-D run's vectors (written with 3 components) have a zero z
component, a 3-D run's (its points spanning z) may not. It then writes ``solution_paraview.xdmf`` (the same data as
one grid per time step, declared double precision, see ``sdm_dolfinx/render.py``), checks it
gives the same ranges (up to float32 round-off: ParaView reads ``solution.xdmf`` in single
precision) as a single dataset carrying all four arrays, and, with ``--png``, renders it: the membrane
warped by its displacement over the obstacle plane, a 2-D elastic body warped by its
displacement, coloured by the displacement magnitude (last time step), or a 3-D body (the ball)
at the time of its largest contact stress, cut by the plane y = 0, over the plane z = 0.

Exit status 0 when every check passed, 1 otherwise; ``--json`` writes the summary (times,
number of points and cells, and each array's per-time range) for comparison with h5py.
"""
import argparse
import importlib.util
import json
import os
import sys
from pathlib import Path

from paraview import servermanager
from paraview.simple import (Clip, ColorBy, GetActiveViewOrCreate, Plane, Render, SaveScreenshot, Show, Text,
                             WarpByScalar, WarpByVector, Xdmf3ReaderS)
from vtkmodules.util.numpy_support import vtk_to_numpy

import numpy as np

#: the arrays every run's file holds (``Vbar_W`` too when H^h differs from W^h in the M formulation)
FIELDS = ("displacement", "velocity", "contact_stress", "active")
ROOT = Path(__file__).resolve().parent.parent


def _render_module():
    """sdm_dolfinx/io/xdmf_reader.py loaded by path (it needs only the standard library at load time)."""
    spec = importlib.util.spec_from_file_location("sdm_render", ROOT / "sdm_dolfinx" / "io" / "xdmf_reader.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def leaves(data):
    """The non-composite datasets inside a (possibly nested) multiblock."""
    if data is None:
        return []
    if data.IsA("vtkMultiBlockDataSet") or data.IsA("vtkMultiPieceDataSet"):
        out = []
        for i in range(data.GetNumberOfBlocks() if data.IsA("vtkMultiBlockDataSet") else data.GetNumberOfPieces()):
            out += leaves(data.GetBlock(i) if data.IsA("vtkMultiBlockDataSet") else data.GetPiece(i))
        return out
    return [data]


def stored_fields(path):
    """The field names ``path`` lists (its Attribute names), in the file's order."""
    import xml.etree.ElementTree as ET
    names = []
    for a in ET.parse(path).getroot().iter("Attribute"):
        if a.get("Name") not in names:
            names.append(a.get("Name"))
    return tuple(names)


def inspect(path, fields=None):
    """Read ``path`` with Xdmf3ReaderS at every time step; returns (summary dict, list of failures).
    ``fields``: the arrays expected (default: every field the file lists, at least :data:`FIELDS`)."""
    fields = fields or stored_fields(path)
    failures = []
    reader = Xdmf3ReaderS(FileName=[str(path)])
    reader.UpdatePipelineInformation()
    times = [float(t) for t in reader.TimestepValues]
    failures += [f"{path.name}: field {f!r} is not listed" for f in FIELDS if f not in fields]
    if not times:
        failures.append(f"{path.name}: no time steps")
    elif times[0] != 0.0 or any(b <= a for a, b in zip(times, times[1:])):
        failures.append(f"{path.name}: times do not start at 0 and increase: {times[:5]}...")
    summary = {"file": str(path), "times": times, "arrays": {f: {"components": None, "min": [], "max": []}
                                                            for f in fields}}
    for t in times:
        reader.UpdatePipeline(t)
        blocks = leaves(servermanager.Fetch(reader))
        summary.setdefault("blocks", len(blocks))
        arrays = {}
        for b in blocks:
            if b.GetNumberOfPoints():
                z = vtk_to_numpy(b.GetPoints().GetData())[:, 2]
                summary["dim"] = max(summary.get("dim", 2), 3 if float(z.max() - z.min()) > 0 else 2)
            for data, centre in ((b.GetPointData(), "points"), (b.GetCellData(), "cells")):
                for i in range(data.GetNumberOfArrays()):
                    name = data.GetArrayName(i)
                    if name in arrays:
                        failures.append(f"{path.name}, t = {t}: array {name!r} appears in two blocks")
                    arrays[name] = (vtk_to_numpy(data.GetArray(i)).copy(), b.GetNumberOfPoints(), b.GetNumberOfCells(),
                                    centre)
        for f in fields:
            if f not in arrays:
                failures.append(f"{path.name}, t = {t}: array {f!r} missing (found {sorted(arrays)})")
                continue
            a, npts, ncells, centre = arrays[f]
            summary["n_points"], summary["n_cells"] = npts, ncells
            info = summary["arrays"][f]
            info["components"], info["centre"] = 1 if a.ndim == 1 else a.shape[1], centre
            if a.shape[0] != (npts if centre == "points" else ncells):
                failures.append(f"{path.name}, t = {t}: {f} has {a.shape[0]} values for {npts} points, {ncells} cells")
            if not np.all(np.isfinite(a)):
                failures.append(f"{path.name}, t = {t}: {f} has non-finite values")
            info["min"].append(float(np.min(a)))
            info["max"].append(float(np.max(a)))
        if "active" in arrays and "contact_stress" in arrays:
            act, stress = arrays["active"][0], arrays["contact_stress"][0]
            # the XDMF writer interpolates into the mesh's geometry space: round-off around 0 and 1
            tol = 1e-12
            if act.min() < -tol or act.max() > 1 + tol:
                failures.append(f"{path.name}, t = {t}: active outside [0, 1]: [{act.min()}, {act.max()}]")
            scale = max(float(np.max(np.abs(stress))), 1e-300)
            if stress.min() < -tol * scale:
                failures.append(f"{path.name}, t = {t}: negative contact stress {stress.min()}")
            if np.any(np.abs(stress[act < tol]) > tol * scale) or np.any(act[stress > tol * scale] < tol):
                failures.append(f"{path.name}, t = {t}: contact stress and active set disagree")
        if "displacement" in arrays and arrays["displacement"][0].ndim == 2:
            d = arrays["displacement"][0]
            if d.shape[1] == 3 and summary.get("dim") == 2 and np.any(d[:, 2] != 0):
                failures.append(f"{path.name}, t = {t}: 2-D displacement with a nonzero z component")
    return summary, failures


def render(path, png, run, summary=None):
    """A picture of the merged file (needs an OpenGL context: xvfb-run): its last time step, or for a
    3-D run (``summary["dim"]``) the time of the largest contact stress."""
    reader = Xdmf3ReaderS(FileName=[str(path)])
    reader.UpdatePipelineInformation()
    t = reader.TimestepValues[-1]
    three_d = (summary or {}).get("dim") == 3
    if three_d:
        peak = summary["arrays"]["contact_stress"]["max"]
        t = summary["times"][int(np.argmax(peak))]
    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [800, 600]
    view.ViewTime = t
    view.OrientationAxesVisibility = 0
    reader.UpdatePipeline(t)
    scalar = reader.PointData["displacement"].GetNumberOfComponents() == 1
    params = run.get("problem", {}).get("parameters", {})
    if scalar:                                   # the membrane: z = 10 u over the obstacle z = 10 * obstacle
        warped = WarpByScalar(Input=reader, Scalars=["POINTS", "displacement"], ScaleFactor=10.0)
        plane = Plane(Origin=[-0.15, -0.15, 10 * params.get("obstacle", 0.0) - 2e-3],
                      Point1=[1.15, -0.15, 10 * params.get("obstacle", 0.0) - 2e-3],
                      Point2=[-0.15, 1.15, 10 * params.get("obstacle", 0.0) - 2e-3])
        pd = Show(plane, view)
        pd.DiffuseColor = [0.55, 0.55, 0.55]
        pd.ColorArrayName = ["POINTS", ""]
        d = Show(warped, view)
        ColorBy(d, ("POINTS", "displacement"))
        view.CameraPosition = [1.8, -1.7, 1.1]
        view.CameraFocalPoint = [0.5, 0.5, 0.05]
        view.CameraViewUp = [0, 0, 1]
    elif three_d:                                # a 3-D body (the ball): cut by y = 0, over the plane z = 0
        warped = WarpByVector(Input=reader, Vectors=["POINTS", "displacement"], ScaleFactor=1.0)
        cut = Clip(Input=warped)
        cut.ClipType = "Plane"
        cut.ClipType.Origin = [0.0, 0.0, 0.0]
        cut.ClipType.Normal = [0.0, 1.0, 0.0]
        cut.Invert = 0                           # keep y >= 0: the cut face looks at the camera (at y < 0)
        b = reader.GetDataInformation().GetBounds()
        w = 0.65 * max(b[1] - b[0], b[3] - b[2])
        cx, cy = 0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3])
        plane = Plane(Origin=[cx - w, cy - w, 0.0], Point1=[cx + w, cy - w, 0.0], Point2=[cx - w, cy + w, 0.0])
        pd = Show(plane, view)
        pd.DiffuseColor = [0.6, 0.6, 0.6]
        pd.ColorArrayName = ["POINTS", ""]
        d = Show(cut, view)
        ColorBy(d, ("POINTS", "displacement", "Z"))
        title = Show(Text(Text=f"3-D run at t = {t:.4g} (largest contact stress): the half y >= 0 near the "
                           f"contact, coloured by u_z, over the plane z = 0"), view)
        title.FontSize = 11
        title.WindowLocation = "Upper Center"
        Render(view)                             # the first render resets the camera: set it afterwards
        size = b[5] - b[4]                       # the close-up of the contact zone, about 0.6 diameters wide
        view.CameraPosition = [cx + 0.3 * size, cy - 1.0 * size, 0.45 * size]
        view.CameraFocalPoint = [cx, cy, 0.1 * size]
        view.CameraViewUp = [0, 0, 1]
    else:                                        # an elastic body, true scale, in its plane
        warped = WarpByVector(Input=reader, Vectors=["POINTS", "displacement"], ScaleFactor=1.0)
        d = Show(warped, view)
        ColorBy(d, ("POINTS", "displacement", "Magnitude"))
        view.InteractionMode = "2D"
        view.ResetCamera()
    d.RescaleTransferFunctionToDataRange(True, False)
    d.SetScalarBarVisibility(view, True)
    d.SetRepresentationType("Surface With Edges")
    Render(view)
    SaveScreenshot(str(png), view, ImageResolution=[800, 600])


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path, help="a run's output folder (or its solution.xdmf)")
    p.add_argument("--json", type=Path, help="write the summary here")
    p.add_argument("--png", type=Path, help="render the last time step here (run under xvfb-run -a)")
    args = p.parse_args(argv)
    xdmf = args.run / "solution.xdmf" if args.run.is_dir() else args.run
    run_json = xdmf.parent / "run.json"
    run = json.loads(run_json.read_text()) if run_json.exists() else {}
    raw, failures = inspect(xdmf)
    merged_path = _render_module().merge_xdmf(xdmf)
    merged, more = inspect(merged_path)
    failures += more
    if merged.get("blocks") != 1:
        failures.append(f"{merged_path.name}: {merged.get('blocks')} blocks, expected one dataset with all arrays")
    if raw["times"] != merged["times"]:
        failures.append("the merged file has other times than solution.xdmf")
    # solution.xdmf declares no precision: ParaView reads it in single precision (Xdmf's default),
    # the merged file in double; the ranges agree to float32 round-off
    for f in raw["arrays"]:
        a, b = raw["arrays"][f], merged["arrays"].get(f, {"min": [], "max": []})
        a, b = np.array([a["min"], a["max"]]), np.array([b["min"], b["max"]])
        if a.shape != b.shape or np.any(np.abs(a - b) > 2 * np.finfo(np.float32).eps * max(np.abs(b).max(), 1e-300)):
            failures.append(f"{f}: the merged file's ranges differ from solution.xdmf's")
    summary = {"paraview": servermanager.vtkSMProxyManager.GetParaViewSourceVersion(),
               "reader": "Xdmf3ReaderS", "raw": raw, "merged": merged, "failures": failures}
    if args.png:
        render(merged_path, args.png, run, merged)
        summary["png"] = str(args.png)
    if args.json:
        args.json.write_text(json.dumps(summary, indent=1))
    n = len(raw["times"])
    print(f"paraview-check: {xdmf}: {n} time steps (t = {raw['times'][0]:g} .. {raw['times'][-1]:g}), "
          f"{raw.get('n_points')} points, {raw.get('n_cells')} cells, {raw.get('blocks')} blocks "
          f"({merged_path.name}: {merged.get('blocks')})")
    for f, a in raw["arrays"].items():
        if a["min"]:
            print(f"  {f:15s} {a['components']} component(s) on {a['centre']}, range [{min(a['min']):.4g}, {max(a['max']):.4g}]")
    if args.png:
        print(f"  rendered {args.png}")
    for msg in failures:
        print(f"  FAILED: {msg}")
    print("paraview-check: " + ("ok" if not failures else f"{len(failures)} check(s) failed"))
    return 0 if not failures else 1


if __name__ == "__main__":
    status = main()
    # sys.exit() after a render makes pvpython 5.11 re-initialise its X window at shutdown and
    # abort (GLXBadContext under Xvfb); leave without running the finalisers instead
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
