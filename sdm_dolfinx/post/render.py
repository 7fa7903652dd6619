"""Pictures and animations of a run from its ``solution.xdmf`` (optional helpers).

Everything here reads the files a run wrote (``solution.xdmf`` + ``.h5``, ``run.json``), so it
works the same for runs made with the command line or the Python API, on any number of ranks
(call it on one rank: Debian's h5py is serial).

:func:`picture` and :func:`animation` draw a membrane warped over its obstacle, or a deformed
body (2-D, or a 3-D body's surface) coloured by its von Mises stress, with the obstacle its
problem declares (:mod:`.render_obstacle`, which builds the Problem again from run.json), with
pyvista off-screen when it is installed (``pip install pyvista imageio``; its VTK wheel renders
through EGL/OSMesa without a display; :mod:`.render_pv`) and with matplotlib otherwise
(:mod:`.render_mpl`). What cannot be drawn, or a time, scale or file name that would draw
something else than asked, raises :class:`RenderError` before anything is written. Reading the
files and the ParaView-friendly XDMF are in :mod:`sdm_dolfinx.io.xdmf_reader`; their names are
available here as well (``render.read_xdmf``, ``render.merge_xdmf``, ...).

The command is ``python -m sdm_dolfinx render RUN_DIR [--png F] [--gif F] [--time T]
[--merge]`` (:mod:`sdm_dolfinx.cli.render`); running this file is only the pyvista child
process (see :func:`_in_child`).

This module, :mod:`sdm_dolfinx.io.xdmf_reader`, :mod:`.render_pv` and :mod:`.render_mpl` import
only the standard library at load time (numpy, h5py, pyvista and matplotlib inside the
functions), so the child process loads this file by path, and it then loads those by path too.
"""
import json
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
    from sdm_dolfinx.post import render_mpl, render_pv
    from sdm_dolfinx.io import xdmf_reader as xdmf
else:                      # loaded by path (pvpython, the pyvista child process)
    xdmf, render_mpl, render_pv = (_load_sibling("../io/xdmf_reader.py"), _load_sibling("render_mpl.py"),
                                   _load_sibling("render_pv.py"))

# the names demos, tests and the paper use as render.<name>
Series, read_xdmf, merge_xdmf, merged_path, von_mises = (xdmf.Series, xdmf.read_xdmf, xdmf.merge_xdmf,
                                                          xdmf.merged_path, xdmf.von_mises)
RenderError = xdmf.RenderError
p2_edge_lines, draw_foundation, draw_disc_mesh = (render_mpl.p2_edge_lines, render_mpl.draw_foundation,
                                                  render_mpl.draw_disc_mesh)


class RenderWarning(UserWarning):
    """Something a picture leaves out, said once (the obstacle a run's problem does not let us know)."""


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


def _run_child(what, kwargs, xdmf_path):
    """Draw in a fresh process: ``python -P render.py WHAT XDMF`` with the keyword arguments as
    JSON on its standard input (an obstacle's points may exceed a command line's length)."""
    cmd = [sys.executable, "-P", str(Path(__file__).resolve()), what, str(xdmf_path)]
    p = subprocess.run(cmd, input=json.dumps(kwargs), capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"rendering in a child process failed ({' '.join(cmd)}):\n{p.stderr[-2000:]}")
    return "pyvista"


# ------------------------------------------------------------------------ what is drawn
def kind_of(series):
    """``"membrane"`` (a scalar u on a 2-D mesh), ``"solid"`` (a vector u in 2-D) or ``"solid3d"``.

    Raises:
        RenderError: no output time yet, no displacement, a 1-D run, a scalar u on a 3-D mesh, cells
            other than triangles and tetrahedra.
    """
    if not series.times:
        raise RenderError(f"{series.xdmf} holds no output time yet")
    if series.tdim == 1:
        raise RenderError(f"{series.xdmf} is a 1-D run: render draws 2-D and 3-D runs; plot u(x, t) from its "
                          f"time series, or open solution.xdmf in ParaView (Plot Over Line)")
    scalar = series.field("displacement", series.times[0]).ndim == 1
    if scalar and series.tdim == 2:
        return "membrane"
    if scalar:
        raise RenderError(f"{series.xdmf}: a scalar u on a 3-D mesh (render draws a scalar u as a surface over a "
                          f"2-D mesh): open solution.xdmf in ParaView")
    return "solid3d" if series.tdim == 3 else "solid"


def _unit(series, *keys):
    """The first word of run.json's ``problem.units`` of the first of ``keys`` it has ("-" reads
    dimensionless), "dimensionless" for a dimensionless problem, else None."""
    units = series.run.get("problem", {}).get("units", {})
    for key in keys:
        if key in units and str(units[key]).split():
            word = str(units[key]).split()[0]
            return "dimensionless" if word == "-" else word
    if str(units.get("all", "")).startswith("dimensionless"):
        return "dimensionless"
    return None


def _time_label(series, t):
    """``t = 0.300`` (dimensionless) or ``t = 12.50 ms`` (a run in seconds shorter than 1 s)."""
    t, unit = series.times[series.index(t)], _unit(series, "t")
    if unit == "s" and series.times[-1] < 1.0:
        return f"t = {1e3 * t:.2f} ms"
    return f"t = {t:.3f}" + (f" {unit}" if unit not in (None, "dimensionless") else "")


class Look:
    """What a picture shows beside the mesh: the colour (its values at the nodes and its title
    with the unit from run.json) and the title line (time, contacts, scale, obstacle)."""

    def __init__(self, series, kind, scale, obstacle):
        self.series, self.kind, self.scale, self.obstacle = series, kind, scale, obstacle
        unit_of = {"stress": ("lame_mu", "lame_lambda", "E"), "u": ("u_probe", "u", "displacement")}
        if kind == "membrane":
            self.colour, what, unit = "u", "displacement u", _unit(series, *unit_of["u"])
        elif series.lame() is not None:
            self.colour, unit = "stress", _unit(series, *unit_of["stress"])
            what = f"von Mises stress{' (Cauchy)' * (series.material != 'linear')}{' (plane strain)' * (kind == 'solid')}"
        else:                                          # no Lamé parameters: the stress is not known here
            self.colour, what, unit = "|u|", "displacement |u|", _unit(series, *unit_of["u"])
        self.colour_title = what.replace(" (", "\n(") + "\n" + (f"({unit})" if unit else "(unit not in run.json)")
        length = _unit(series, *unit_of["u"])
        self.length = f" {length}" if length not in (None, "dimensionless") else ""     # for lengths in titles

    def values(self, u):
        """The colour at the nodes for the displacement ``u``."""
        import numpy as np
        if self.colour == "u":
            return u
        if self.colour == "stress":
            return self.series.nodal_von_mises(u)
        return np.linalg.norm(u[:, :self.series.gdim], axis=1)

    def range(self, times):
        """One colour scale for ``times``: [min of u and a flat obstacle, max of u] (membrane), [0, max] otherwise."""
        import numpy as np
        values = [self.values(self.series.field("displacement", t)) for t in times]
        lo = min(float(np.min(v)) for v in values) if self.kind == "membrane" else 0.0
        if self.kind == "membrane" and self.obstacle.get("flat") is not None:      # from the obstacle up
            lo = min(lo, self.obstacle["flat"])
        hi = max(float(np.max(v)) for v in values)
        return [lo, hi if hi > lo else lo + max(abs(lo), 1.0) * 1e-12]

    def obstacle_shape(self, t):
        """The obstacles' surface to draw at the time ``t`` (``points`` (n, 3) and ``cells`` (m, 2 or 3)
        arrays: the fixed one, or the one of the nearest time), or None (a bound, or nothing, is drawn)."""
        import numpy as np
        shapes = self.obstacle.get("shapes")
        if not shapes:
            return None
        s = shapes[0] if len(shapes) == 1 else min(shapes, key=lambda s: abs(s["time"] - float(t)))
        return np.asarray(s["points"], dtype=float).reshape(-1, 3), np.asarray(s["cells"], dtype=np.int64)

    def title(self, t, n_active, marker):
        """The title line at time ``t`` with ``n_active`` vertices in contact, drawn in ``marker``."""
        o = self.obstacle
        none = "contact between bodies" if self.series.run.get("problem", {}).get("contact_pairs") else "no obstacle"
        said = o.get("note") or (none if "none" in o else "the obstacle is not drawn (see the warning)")
        if self.kind == "membrane":
            return (f"membrane, {_time_label(self.series, t)}: vertical scale x{self.scale:g}; {said}; "
                    f"{marker}: vertices in contact ({n_active})")
        return (f"{self.series.problem_name or 'body'}, {_time_label(self.series, t)}: vertices in contact "
                f"({marker}): {n_active}, " + ("true scale" if self.scale == 1 else f"displacement x{self.scale:g}")
                + f"; {said}")


#: the obstacles' surfaces are clipped to the box about the drawn body's whose half sides are this many
#: times its largest side
OBSTACLE_BOX = 0.75


def obstacle_box(series, times, scale):
    """(lo, hi) (3,): the box the obstacles' surfaces are drawn in, about the body drawn at ``times``."""
    import numpy as np
    from sdm_dolfinx.obstacles.surface import enlarged_box
    lo, hi = render_pv.extent(series, times, scale)
    return enlarged_box(np.r_[lo, np.zeros(3 - len(lo))], np.r_[hi, np.zeros(3 - len(hi))], OBSTACLE_BOX)


def obstacle_of(series, time=None, times=None, scale=None):
    """The obstacle the run's problem declares (:mod:`.render_obstacle`; a moving one where it is at
    ``time``, the picture's, or, problems with ``obstacles``, at each of ``times``, an animation's: all
    the stored times when neither is given), computed once per Series (a moving one once per time), unless
    one was given (``series.obstacle``); a :class:`RenderWarning` says why when it cannot be known (it is
    then not drawn). ``scale``: the picture's (:func:`check_scale`), which the obstacles' box follows."""
    given = getattr(series, "obstacle", None)
    if given is not None:
        return given
    cache = getattr(series, "obstacles", None)
    if cache is None:
        cache = series.obstacles = {}
    if time is None and times is None:
        times = series.times
    scale = check_scale(kind_of(series), scale)
    drawn = [time] if times is None else list(times)
    key = "fixed" if "fixed" in cache else (time, None if times is None else tuple(times), scale)
    if key not in cache:
        if not __package__:
            return {"unknown": "the obstacle is computed by the package (dolfinx), not in this process"}
        import warnings
        from sdm_dolfinx.post.render_obstacle import declared_obstacle
        declares = kind_of(series) != "membrane" and (series.run.get("problem") or {}).get("obstacles")
        box = obstacle_box(series, drawn, scale) if declares else None
        found = declared_obstacle(series.run, time, times, box)
        key = key if found.get("moving") or "shapes" in found else "fixed"
        cache[key] = found
        if "unknown" in found:
            warnings.warn(f"the obstacle is not drawn: {found['unknown']}", RenderWarning, stacklevel=3)
    return cache[key]


# ------------------------------------------------------------------------ checks
def check_time(series, time):
    """The stored output time drawn for ``time`` (None: the last one): the nearest one.

    Raises:
        RenderError: ``time`` is not a finite number, or lies outside the stored output times.
    """
    import math
    kind_of(series)
    if time is None:
        return series.times[-1]
    try:
        t = float(time)
    except (TypeError, ValueError):
        raise RenderError(f"time {time!r} is not a number") from None
    first, last = series.times[0], series.times[-1]
    slack = 1e-9 * max(abs(first), abs(last), last - first)
    if not math.isfinite(t):
        raise RenderError(f"time {t:g} is not a finite number")
    if not first - slack <= t <= last + slack:
        raise RenderError(f"time {t:g} is outside the run's output times [{first:g}, {last:g}] "
                          f"({len(series.times)} stored)")
    return series.times[series.index(t)]


def check_scale(kind, scale):
    """The displacement magnification: ``scale``, or 10 (membrane) or 1 (bodies) when None.

    Raises:
        RenderError: not a finite number > 0.
    """
    import math
    if scale is None:
        return 10.0 if kind == "membrane" else 1.0
    try:
        s = float(scale)
    except (TypeError, ValueError):
        raise RenderError(f"scale {scale!r} is not a number") from None
    if not (math.isfinite(s) and s > 0):
        raise RenderError(f"scale {s:g}: the displacement magnification must be a finite number > 0")
    return s


def check_output(path, suffixes):
    """``path`` as a Path whose suffix is one of ``suffixes`` (and an .mp4 only where it can be written).

    Raises:
        RenderError: another suffix; .mp4 without imageio-ffmpeg (pyvista) or ffmpeg (matplotlib).
    """
    import importlib.util
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in suffixes:
        raise RenderError(f"{path}: the file must end in {' or '.join(suffixes)} (it is written in that format)")
    if suffix == ".mp4":
        if have_pyvista() and importlib.util.find_spec("imageio_ffmpeg") is None:
            raise RenderError(f"{path}: an MP4 needs imageio-ffmpeg (pip install imageio-ffmpeg); or write a .gif")
        if not have_pyvista():
            from matplotlib.animation import FFMpegWriter
            if not FFMpegWriter.isAvailable():
                raise RenderError(f"{path}: an MP4 needs ffmpeg (apt-get install ffmpeg); or write a .gif")
    return path


def _prepare(run, time, scale, obstacle):
    series = run if isinstance(run, Series) else read_xdmf(run)
    kind = kind_of(series)
    if obstacle is not None:
        series.obstacle = obstacle
    return series, kind, check_scale(kind, scale)


# ------------------------------------------------------------------------ public API
def picture(run, png, time=None, scale=None, size=None, obstacle=None):
    """A PNG of a run at one output time (default: the last): pyvista if installed, else matplotlib.

    Membrane runs: the membrane warped by its displacement (``scale``, default 10) over its
    obstacle, coloured by the displacement, with the vertices in contact in red. Bodies (2-D or
    3-D, vector u): the deformed body (``scale``, default 1 = true scale; in 3-D its surface)
    coloured by its von Mises stress (2-D: plane strain) when run.json's problem parameters hold
    ``lame_lambda`` and ``lame_mu``, else by |u|, with the obstacle the problem declares
    (:mod:`.render_obstacle`). Colour bars carry the unit from run.json's problem units.

    Args:
        run: the run folder or its ``solution.xdmf``, or a :class:`Series`.
        png: output file (.png).
        time: the output time to draw (the nearest stored one; outside them: RenderError).
        scale: displacement magnification (a finite number > 0).
        size: picture size in pixels (default 900 x 700; a 3-D body, in two views: 1200 x 600).
        obstacle: the obstacle to draw as :func:`.render_obstacle.declared_obstacle` gives it
            (default: the one the run's problem declares).

    Returns:
        ``"pyvista"`` or ``"matplotlib"``: which one drew it.

    Raises:
        RenderError: a run or a request that cannot be drawn (nothing written).
    """
    series, kind, scale = _prepare(run, time, scale, obstacle)
    t, png = check_time(series, time), check_output(png, (".png",))
    obstacle = obstacle_of(series, t, scale=scale)
    look = Look(series, kind, scale, obstacle)
    size = tuple(size or ((1200, 600) if kind == "solid3d" else (900, 700)))
    png.parent.mkdir(parents=True, exist_ok=True)
    if not have_pyvista():
        render_mpl.picture_mpl(series, png, t, scale, look)
        return "matplotlib"
    if _in_child():
        return _run_child("picture", {"png": str(png.resolve()), "time": t, "scale": scale, "size": list(size),
                                      "obstacle": obstacle}, series.xdmf)
    render_pv.picture(series, png, t, scale, look.range([t]), look, obstacle, size)
    return "pyvista"


def animation(run, path, times=None, scale=None, size=None, fps=12, obstacle=None):
    """A GIF (or MP4 if ``path`` ends in .mp4 and imageio-ffmpeg is installed) of a run.

    Args:
        run: the run folder or its ``solution.xdmf``, or a :class:`Series`.
        path: output file (.gif or .mp4).
        times: output times to show (default: all stored ones; each must be one of them up to
            the nearest, see :func:`picture`).
        scale: displacement magnification (see :func:`picture`).
        size: frame size in pixels (default 640 x 640; a 3-D body, in two views: 960 x 480).
        fps: frames per second.
        obstacle: see :func:`picture`.

    Returns:
        ``"pyvista"`` or ``"matplotlib"``.

    Raises:
        RenderError: a run or a request that cannot be drawn (nothing written).
    """
    series, kind, scale = _prepare(run, None, scale, obstacle)
    times = [check_time(series, t) for t in (series.times if times is None else times)]
    path = check_output(path, (".gif", ".mp4"))
    if not times:
        raise RenderError(f"{path}: no time to animate")
    obstacle = obstacle_of(series, times=times, scale=scale)
    look = Look(series, kind, scale, obstacle)
    size = tuple(size or ((960, 480) if kind == "solid3d" else (640, 640)))
    path.parent.mkdir(parents=True, exist_ok=True)
    if not have_pyvista():
        render_mpl.animation_mpl(series, path, times, scale, look, fps)
        return "matplotlib"
    if _in_child():
        return _run_child("animation", {"path": str(path.resolve()), "times": list(times), "scale": scale,
                                        "size": list(size), "fps": fps, "obstacle": obstacle}, series.xdmf)
    render_pv.animation(series, path, times, scale, look.range(times), look, obstacle, size, fps)
    return "pyvista"


def _child(argv):
    """The child process of :func:`_run_child`: ``picture`` or ``animation`` of XDMF with the
    JSON keyword arguments read from standard input (the public command is ``python -m sdm_dolfinx render``)."""
    what, src = argv
    kwargs = json.loads(sys.stdin.read())
    kwargs["size"] = tuple(kwargs["size"])
    {"picture": picture, "animation": animation}[what](read_xdmf(src), **kwargs)
    return 0


if __name__ == "__main__":
    raise SystemExit(_child(sys.argv[1:]))
