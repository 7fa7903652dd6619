"""The XDMF output as viewers see it: ParaView's own reader (skipped without ParaView), the merged
XDMF for ParaView, and pictures (pyvista if installed, else matplotlib).

ParaView: Debian's ``paraview`` package (``apt-get install -y paraview xvfb``, ~2 min); the
checks run ``pvpython scripts/paraview_check.py`` and the ParaView demo script in a child
process on rank 0 (without the MPI job's variables) and compare with h5py's reading.
"""
import json
import os
import shutil
import subprocess
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import disc, membrane, simulate
from sdm_dolfinx.post import render
from sdm_dolfinx.problems import ball

COMM = MPI.COMM_WORLD
pytestmark = pytest.mark.paraview
ROOT = Path(__file__).resolve().parents[2]
PVPYTHON = shutil.which("pvpython")
XVFB_RUN = shutil.which("xvfb-run")
#: xvfb-run's default screen, and no server reset between pvpython's connections (see render_png)
XVFB_ARGS = "-screen 0 1280x1024x24 -noreset"
#: the runs below are M-formulation runs with H^h != W^h: Vbar_W is written beside the velocity
FIELDS = ("displacement", "velocity", "Vbar_W", "contact_stress", "active")
#: CI (.ci/run) installs ParaView and sets SDM_REQUIRE_PARAVIEW=1: there a missing ParaView fails, not skips
REQUIRED = os.environ.get("SDM_REQUIRE_PARAVIEW", "") not in ("", "0")
needs_paraview = pytest.mark.skipif(
    PVPYTHON is None and not REQUIRED,
    reason="ParaView is not installed (Debian: apt-get install -y paraview xvfb, or `make paraview-check`, "
           "which installs it)")
needs_paraview_and_xvfb = pytest.mark.skipif(
    (PVPYTHON is None or XVFB_RUN is None) and not REQUIRED,
    reason="ParaView and Xvfb are not installed (rendering with pvpython needs an X display; "
           "Debian: apt-get install -y paraview xvfb, or `make paraview-check`)")


def require(*tools):
    """Fail (rather than crash) when SDM_REQUIRE_PARAVIEW is set and a tool is missing."""
    missing = [name for name, path in tools if path is None]
    assert not missing, f"SDM_REQUIRE_PARAVIEW is set but {', '.join(missing)} is not on the PATH"


def clean_env():
    """The environment without the MPI job's variables: pvpython links MPI and would try to join the job."""
    keep = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM")
    return {k: v for k, v in os.environ.items()
            if k in keep or not k.startswith(("OMPI_", "PMIX_", "OPAL_", "PRTE_", "HYDRA_", "PMI_"))}


@pytest.fixture(scope="module")
def runs():
    """A membrane run that reaches the obstacle, a disc run that reaches the foundation and a ball run
    near its maximal compression (3-D: a z displacement of its own), on disk."""
    path = tempfile.mkdtemp(prefix="sdm_pv_") if COMM.rank == 0 else None
    path = Path(COMM.bcast(path, root=0))
    # membrane: free fall reaches u = 0 at t ~ 0.26
    simulate(membrane.problem(N=6), pair="P1+/P0", dt=1e-2, T=0.4, out=path / "membrane", write_every=5)
    # disc: the lowest point touches at t ~ 9.6 ms (vector field, quadratic geometry)
    simulate(disc.problem(level=1), pair="P2/P1", dt=2.5e-4, T=0.0115, out=path / "disc", write_every=4)
    # ball: touches at t = 0.1 ms, largest force near 2 ms (P2 tetrahedra, curved)
    simulate(ball.problem(level=1), pair="P2/P1", dt=1e-4, T=2.4e-3, out=path / "ball", write_every=4)
    yield {"membrane": path / "membrane", "disc": path / "disc", "ball": path / "ball"}
    COMM.Barrier()
    if COMM.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def h5_reference(run):
    """Per field and output time, (min, max) of the stored values, read with h5py (rank 0)."""
    import h5py
    with h5py.File(run / "solution.h5", "r") as h5:
        out = {}
        for f in h5["Function"]:
            g = h5["Function"][f]
            keys = sorted(g, key=lambda k: float(k.replace("_", ".")))
            out[f] = [(float(np.min(g[k][:])), float(np.max(g[k][:]))) for k in keys]
        return out, len(h5["Mesh/mesh/geometry"])


def render_png(script, args, png):
    """Run the pvpython ``script`` with ``args`` and ``--png png`` under xvfb-run; the PNG's RGB
    values. Xvfb runs with -noreset: by default an X server resets when its last client disconnects,
    and pvpython connects, disconnects (its OpenGL capability check) and connects again, so its
    second connection could meet a resetting server ("bad X server connection", SIGABRT): on one
    core, as mpirun binds rank 0 and its children, about half of the renders failed so, none of 12
    with -noreset. A failure shows the start of pvpython's error output (the X or GL message) as
    well as its end (the stack trace)."""
    from PIL import Image
    cmd = [XVFB_RUN, "-a", "-s", XVFB_ARGS, PVPYTHON, str(script)] + list(args) + ["--png", str(png)]
    p = subprocess.run(cmd, capture_output=True, text=True, env=clean_env(), timeout=300)
    assert p.returncode == 0, (f"{Path(script).name} failed (exit {p.returncode}):\n"
                               f"{p.stdout[-2000:]}\n{p.stderr[:1500]}\n[...]\n{p.stderr[-1000:]}")
    return np.asarray(Image.open(png).convert("RGB"), dtype=float)


def on_rank0(check):
    """Run ``check()`` on rank 0 only; every rank passes or fails with its message."""
    message = None
    if COMM.rank == 0:
        try:
            check()
        except AssertionError as e:
            message = str(e) or "assertion failed"
    message = COMM.bcast(message, root=0)
    assert message is None, message


# ------------------------------------------------------------------------- without ParaView
@pytest.mark.parametrize("name", ["membrane", "disc", "ball"])
def test_merged_xdmf_holds_every_field_per_time(runs, name):
    def check():
        run = runs[name]
        merged = render.merge_xdmf(run / "solution.xdmf")
        root = ET.parse(merged).getroot()
        top = root.find("Domain").findall("Grid")
        assert len(top) == 1 and top[0].get("CollectionType") == "Temporal"
        steps = top[0].findall("Grid")
        ref, npoints = h5_reference(run)
        assert len(steps) == len(ref["active"])
        for g in steps:
            assert sorted(a.get("Name") for a in g.findall("Attribute")) == sorted(FIELDS)
            assert g.find("Topology") is not None and g.find("Geometry") is not None
        series = render.read_xdmf(merged)
        assert series.fields == sorted(FIELDS) and series.points.shape == (npoints, 3)
        for k, t in enumerate(series.times):
            for f in FIELDS:
                a = series.field(f, t)
                assert (a.min(), a.max()) == ref[f][k], (f, t)
        assert max(series.field("active", t).max() for t in series.times) == pytest.approx(1.0)  # contact
    on_rank0(check)


def test_pictures(runs):
    """A membrane picture and a short disc animation (pyvista off-screen if installed, else matplotlib)."""
    def check():
        from PIL import Image
        out = runs["membrane"].parent
        how = render.picture(runs["membrane"], out / "membrane.png", time=0.3)
        assert how in ("pyvista", "matplotlib")
        img = np.asarray(Image.open(out / "membrane.png").convert("RGB"), dtype=float)
        assert img.shape[0] > 300 and img.std() > 10            # not a blank picture
        series = render.read_xdmf(runs["disc"])
        render.animation(series, out / "disc.gif", times=series.times[-3:], size=(240, 240))
        gif = Image.open(out / "disc.gif")
        assert gif.n_frames == 3
    on_rank0(check)


# ---------------------------------------------------------------------------- with ParaView
@needs_paraview
@pytest.mark.parametrize("name", ["membrane", "disc", "ball"])
def test_paraview_reads_the_output(runs, name):
    """pvpython opens solution.xdmf (Xdmf3ReaderS), steps through time; arrays and ranges match h5py."""
    require(("pvpython", PVPYTHON))
    def check():
        run = runs[name]
        summary = run / "paraview.json"
        p = subprocess.run([PVPYTHON, str(ROOT / "scripts" / "paraview_check.py"), str(run), "--json", str(summary)],
                           capture_output=True, text=True, env=clean_env(), timeout=300)
        assert p.returncode == 0, f"paraview_check failed:\n{p.stdout[-3000:]}\n{p.stderr[-2000:]}"
        s = json.loads(summary.read_text())
        ref, npoints = h5_reference(run)
        # solution.xdmf declares no precision, so ParaView reads it in single precision (Xdmf's
        # default); the merged file declares 8 bytes and must match h5py exactly
        for layout, rtol in (("raw", 2 * np.finfo(np.float32).eps), ("merged", 0.0)):
            got = s[layout]
            assert got["n_points"] == npoints
            assert len(got["times"]) == len(ref["active"]) and got["times"][0] == 0.0
            for f in FIELDS:
                a = got["arrays"][f]
                assert a["components"] == (1 if name == "membrane" or f in ("contact_stress", "active") else 3)
                scale = max(max(abs(lo), abs(hi)) for lo, hi in ref[f])
                err = np.max(np.abs(np.array(list(zip(a["min"], a["max"]))) - np.array(ref[f])), initial=0.0)
                assert err <= rtol * scale, (layout, f, err, scale)
        assert s["raw"]["blocks"] == len(FIELDS) and s["merged"]["blocks"] == 1
        assert max(s["merged"]["arrays"]["contact_stress"]["max"]) > 0
        # a 3-D run moves along z (accepted); a 2-D run's third component is zero (checked by the script)
        assert s["raw"]["dim"] == (3 if name == "ball" else 2)
    on_rank0(check)


@needs_paraview_and_xvfb
def test_paraview_renders_the_ball(runs):
    """paraview_check.py --png renders the ball (3-D) cut by y = 0 at its largest contact stress."""
    require(("pvpython", PVPYTHON), ("xvfb-run", XVFB_RUN))
    def check():
        run = runs["ball"]
        img = render_png(ROOT / "scripts" / "paraview_check.py", [str(run)], run / "paraview.png")
        assert img.shape[:2] == (600, 800) and img.std() > 10
    on_rank0(check)


@needs_paraview_and_xvfb
def test_paraview_renders_the_membrane_demo(runs):
    """demos/paraview_membrane.py renders the membrane on its obstacle to a PNG under xvfb-run."""
    require(("pvpython", PVPYTHON), ("xvfb-run", XVFB_RUN))
    def check():
        img = render_png(ROOT / "demos" / "paraview_membrane.py", [str(runs["membrane"]), "--time", "0.3"],
                         runs["membrane"].parent / "paraview_membrane.png")
        assert img.shape[:2] == (650, 900) and img.std() > 10
        # red contact markers are drawn (the membrane touches the obstacle at t = 0.3)
        red = (img[..., 0] > 180) & (img[..., 1] < 80) & (img[..., 2] < 80)
        assert red.sum() > 20
    on_rank0(check)
