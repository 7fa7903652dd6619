"""# The membrane on its obstacle, in ParaView (a ParaView Python script)

Shows a membrane run (``python -m sdm_dolfinx membrane --out DIR`` or ``make demo``) as a
surface warped by its displacement over the obstacle plane, coloured by the displacement,
with the vertices in contact as red spheres, at any time step of the animation toolbar.

* In the ParaView GUI: *View > Python Shell > Run Script*, or start it with
  ``paraview --script=demos/paraview_membrane.py`` (the run folder then comes from the
  ``SDM_RUN`` variable, default ``demos/output/membrane/P1plus-P0_dt0.001``).
* Without a window, to a picture (rendering needs an X display; ``xvfb-run`` provides one)::

      xvfb-run -a -s "-screen 0 1280x1024x24 -noreset" pvpython demos/paraview_membrane.py RUN_DIR --png membrane.png [--time 0.3]
      xvfb-run -a -s "-screen 0 1280x1024x24 -noreset" pvpython demos/paraview_membrane.py RUN_DIR --frames DIR   # one PNG per step

dolfinx's XDMF stores each field as its own grid, which ParaView shows as four overlapping
blocks, one array each; the script first writes ``solution_paraview.xdmf`` next to it (all
fields on one grid per time step, same HDF5 data; ``python -m sdm_dolfinx render DIR
--merge`` does the same) and opens that. The displacement is exaggerated 10 times
(``--scale``): the membrane hangs 0.02 above a unit square.
"""
import argparse
import importlib.util
import os
import sys
from pathlib import Path

from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetAnimationScene, GetColorTransferFunction,
                             GetScalarBar, Glyph, Plane, Render, SaveScreenshot, Show, WarpByScalar, Xdmf3ReaderS)

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_RUN = ROOT / "demos" / "output" / "membrane" / "P1plus-P0_dt0.001"


def merged_xdmf(run):
    """The run's ``solution_paraview.xdmf``, written from ``solution.xdmf`` if missing or older."""
    spec = importlib.util.spec_from_file_location("sdm_render", ROOT / "sdm_dolfinx" / "io" / "xdmf_reader.py")
    render = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(render)
    src = run / "solution.xdmf"
    dst = render.merged_path(src)
    if not dst.exists() or dst.stat().st_mtime < src.stat().st_mtime:
        render.merge_xdmf(src, dst)
    return dst


def build_scene(run, scale=10.0, obstacle=0.0):
    """Reader, warp, obstacle plane and contact markers in the active render view; returns the view."""
    reader = Xdmf3ReaderS(registrationName="solution", FileName=[str(merged_xdmf(run))])
    reader.UpdatePipelineInformation()
    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [900, 650]
    view.OrientationAxesVisibility = 0
    view.Background = [1.0, 1.0, 1.0]
    try:                                  # ParaView >= 5.10 uses a palette unless told otherwise
        view.UseColorPaletteForBackground = 0
    except AttributeError:
        pass

    # the obstacle: a plane a hair below its height, so that the membrane lying on it stays visible
    plane = Plane(registrationName="obstacle", Origin=[-0.15, -0.15, scale * obstacle - 2e-3],
                  Point1=[1.15, -0.15, scale * obstacle - 2e-3], Point2=[-0.15, 1.15, scale * obstacle - 2e-3])
    pd = Show(plane, view)
    pd.ColorArrayName = ["POINTS", ""]
    pd.DiffuseColor = [0.55, 0.55, 0.55]

    # the membrane: z = scale * u
    warped = WarpByScalar(registrationName="membrane", Input=reader, Scalars=["POINTS", "displacement"],
                          ScaleFactor=scale)
    md = Show(warped, view)
    md.SetRepresentationType("Surface With Edges")
    md.EdgeColor = [0.25, 0.25, 0.25]
    ColorBy(md, ("POINTS", "displacement"))
    lut = GetColorTransferFunction("displacement")
    lut.ApplyPreset("Viridis (matplotlib)", True)
    lut.RescaleTransferFunction(0.0, 0.02)
    md.SetScalarBarVisibility(view, True)

    bar = GetScalarBar(lut, view)
    bar.Title = "displacement u"
    bar.ComponentTitle = ""
    bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
    bar.TitleFontSize, bar.LabelFontSize = 14, 12
    bar.WindowLocation = "Any Location"
    bar.Position = [0.88, 0.25]
    bar.ScalarBarLength = 0.5
    bar.RangeLabelFormat = "%-#.3f"

    # the vertices in contact (active = 1) as red spheres: every vertex gets a sphere scaled
    # by its active flag, so the inactive ones vanish
    glyphs = Glyph(registrationName="contact markers", Input=warped, GlyphType="Sphere")
    glyphs.ScaleArray = ["POINTS", "active"]
    glyphs.ScaleFactor = 0.03
    glyphs.GlyphMode = "All Points"
    gd = Show(glyphs, view)
    gd.ColorArrayName = ["POINTS", ""]
    gd.DiffuseColor = [0.9, 0.1, 0.1]

    view.CameraPosition = [1.5, -1.3, 0.85]
    view.CameraFocalPoint = [0.5, 0.5, 0.02]
    view.CameraViewUp = [0.0, 0.0, 1.0]
    view.CameraViewAngle = 26
    scene = GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    return view, list(reader.TimestepValues)


def main(argv):
    p = argparse.ArgumentParser(description="The membrane on its obstacle, in ParaView.")
    p.add_argument("run", type=Path, nargs="?", default=Path(os.environ.get("SDM_RUN", DEFAULT_RUN)),
                   help="a membrane run's output folder")
    p.add_argument("--png", type=Path, help="save a picture at --time (default: the first time in contact)")
    p.add_argument("--time", type=float, default=None, help="time of the picture")
    p.add_argument("--frames", type=Path, help="save one PNG per output time into this folder")
    p.add_argument("--scale", type=float, default=10.0, help="vertical exaggeration (default 10)")
    args = p.parse_args(argv)
    view, times = build_scene(args.run, args.scale)
    if args.png:
        t = args.time if args.time is not None else times[len(times) // 2]
        view.ViewTime = min(times, key=lambda s: abs(s - t))
        Render(view)
        SaveScreenshot(str(args.png), view, ImageResolution=[900, 650])
        print(f"wrote {args.png} (t = {view.ViewTime:g})")
    if args.frames:
        args.frames.mkdir(parents=True, exist_ok=True)
        for i, t in enumerate(times):
            view.ViewTime = t
            Render(view)
            SaveScreenshot(str(args.frames / f"membrane_{i:04d}.png"), view, ImageResolution=[900, 650])
        print(f"wrote {len(times)} frames to {args.frames}")
    if not (args.png or args.frames):
        Render(view)


# pvpython/pvbatch run this file as __main__; the GUI's "Run Script" too, with an empty argv
main(sys.argv[1:] if __name__ == "__main__" else [])
