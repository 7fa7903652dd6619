"""The obstacle a run's problem declares, where it is, for the pictures of :mod:`.render`.

A Problem states its obstacle as a bound at its constrained vertices: u_c(a_i) >= lower_bound(a_i)
for the component c = ``constraint_component`` of a vector u (the body's point a_i + u(a_i) stays
on the side x_c >= a_i,c + lower_bound(a_i)), or u(a_i) >= lower_bound(a_i) for a scalar u (the
membrane's obstacle under it). Nothing in the run folder but the problem's declaration knows the
bound, so the Problem is built again from ``run.json`` (on one process) and its bound evaluated at
its constrained vertices: the disc's and the ball's floor y = 0 and z = 0, the bar's wall x = 0,
the membrane's plane at the height ``obstacle``, and any user's obstacle, flat or not.

The result is plain data (JSON-able: the pyvista drawing runs in a child process)::

    {"component": c or None (scalar u), "flat": the plane's coordinate x_c (vector u) or height
     (scalar u) when every obstacle point has it, else None, "points": [[x, y, z], ...] the
     obstacle's points above/beside the constrained vertices (scalar u: (x, y, bound)),
     "note": the picture's words for it}

A moving obstacle (``Problem.moving_bound``, ``lower_bound(x, t)``) is evaluated at the picture's
time; an animation, whose frames would each need their own, does not draw it (``{"unknown": ...}``:
the time series' ``obstacle_probe`` has its position at every step).

A problem declaring ``obstacles`` (signed distances, :mod:`sdm_dolfinx.obstacles`) gets their surfaces
(:func:`sdm_dolfinx.obstacles.surface.mesh`: 2-D the outlines' segments, 3-D triangles, clipped to the box
the picture gives)::

    {"component": None, "shapes": [{"time": t or None (fixed), "points": [[x, y, z], ...],
     "cells": [[i, j(, k)], ...]}, ...] one per time asked (a moving obstacle) or one (fixed),
     "moving": bool, "note": the picture's words for them}

so that a moving one is drawn at every frame's time, an animation's too.

Or ``{"none": reason}`` when the problem constrains no vertex, or ``{"unknown": reason}`` when the
obstacle cannot be known (a run of a problem built by hand, a problem file changed since the run).
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx.io import PostprocessError
from sdm_dolfinx.method.discretisation import vertex_coordinates
from sdm_dolfinx.post.rebuild_run import rebuild_problem
from sdm_dolfinx.problems.base import bound_at, one_line
from sdm_dolfinx.problems.contact_pairs import constrained_vertices

#: the Problems built again, by run.json's contents (one picture asks several times and boxes)
_REBUILT: dict = {}

#: obstacle points whose coordinate x_c (or bound) varies by less than this, relative to the
#: body's size (or to the largest bound), form a flat obstacle
FLAT_TOLERANCE = 1e-9


def declared_obstacle(run, time=None, times=None, box=None):
    """The obstacle of the run whose ``run.json`` contents are ``run`` (see the module), a moving one
    at ``time`` (None: a bound is not drawn); ``obstacles`` at each of ``times`` (an animation's, else
    [time]) clipped to ``box`` = (lo, hi) (default: the body's bounding box grown as obstacles.xdmf's).

    Builds the run's Problem again on this process alone (``MPI.COMM_SELF``), once per ``run``.
    """
    if not run:
        return {"unknown": "no run.json beside solution.xdmf"}
    described = run.get("problem") or {}
    source, sha = described.get("source"), described.get("source_sha256")
    if source and sha:
        try:
            now = compat.file_sha256(source)
        except OSError:
            return {"unknown": f"its problem file {source} cannot be read"}
        if now != sha:
            return {"unknown": f"its problem file {source} changed since the run"}
    import json
    key = json.dumps(run, sort_keys=True, default=str)
    if key not in _REBUILT:
        try:
            _REBUILT[key] = rebuild_problem(run, MPI.COMM_SELF)
        except PostprocessError as e:
            _REBUILT[key] = {"unknown": str(e)}
        except Exception as e:      # a user's build: any error is said in one line, the picture drawn without it
            _REBUILT[key] = {"unknown": f"its problem could not be built again ({one_line(e)})"}
    problem = _REBUILT[key]
    if isinstance(problem, dict):
        return problem
    if getattr(problem, "obstacles", None):
        return _shapes(problem, run.get("mesh", {}).get("vertices"), [time] if times is None else times, box)
    return _evaluate(problem, run.get("mesh", {}).get("vertices"), time)


def _shapes(problem, vertices_of_run, times, box):
    """The problem's ``obstacles`` at ``times`` (None: t = 0) within ``box`` (see the module)."""
    from sdm_dolfinx.io.obstacle_xdmf import BOX_FACTOR
    from sdm_dolfinx.obstacles.surface import enlarged_box, mesh
    msh = problem.mesh
    nverts = msh.topology.index_map(0).size_local
    if vertices_of_run is not None and nverts != vertices_of_run:
        return {"unknown": f"its problem, built again, has {nverts} vertices, the run had {vertices_of_run}"}
    obstacles = list(problem.obstacles)
    if box is None:
        box = enlarged_box(msh.geometry.x.min(axis=0), msh.geometry.x.max(axis=0), BOX_FACTOR)
    moving = any(getattr(ob, "moves", False) for ob in obstacles)
    shapes, missing = [], []
    for t in (times if moving else [None]):
        m = mesh(obstacles, 0.0 if t is None else float(t), box)
        shapes.append({"time": None if t is None else float(t), "points": m["points"].tolist(),
                       "cells": m["cells"].tolist()})
        missing = m["missing"]
    def kind(ob):
        return getattr(ob, "kind", type(ob).__name__) + (" (inside)" if getattr(ob, "inside", False) else "")
    kinds = ", ".join(dict.fromkeys(kind(ob) for ob in obstacles))
    note = f"grey: the obstacle{'s' if len(obstacles) > 1 else ''} ({kinds})"
    if moving:
        movers = ", ".join(dict.fromkeys(kind(ob) for ob in obstacles if getattr(ob, "moves", False)))
        at = "each frame's time" if len(shapes) > 1 else f"t = {0.0 if times[0] is None else float(times[0]):.4g}"
        note += f" at {at} (moving: {movers})"
    if missing:
        note += f"; not drawn: {', '.join(missing)}"
    return {"component": None, "shapes": shapes, "moving": moving, "note": note}


def _evaluate(problem, vertices_of_run, time=None):
    msh = problem.mesh
    nverts = msh.topology.index_map(0).size_local
    if vertices_of_run is not None and nverts != vertices_of_run:
        return {"unknown": f"its problem, built again, has {nverts} vertices, the run had {vertices_of_run}"}
    if getattr(problem, "contact_pairs", ()):
        return {"none": f"problem {problem.name!r} has contact pairs: no rigid obstacle (the bodies are drawn)"}
    verts = constrained_vertices(problem, msh)
    if verts.size == 0:
        return {"none": f"problem {problem.name!r} constrains no vertex"}
    moving = getattr(problem, "moving_bound", False)
    if moving and time is None:
        return {"unknown": f"problem {problem.name!r}'s obstacle moves, and an animation draws none (its position "
                           f"per step: the column obstacle_probe)", "moving": True}
    x = vertex_coordinates(msh, verts)                           # (3, n)
    bound = np.asarray(bound_at(problem, x, 0.0 if time is None else float(time)), dtype=float).reshape(-1)
    c = problem.constraint_component if problem.shape else None
    points = x.T.copy()
    if c is None:
        points[:, 2] = bound                                     # the membrane: (x, y, bound)
        values, size = bound, max(np.abs(bound).max(), np.ptp(x[:2], axis=1).max())
    else:
        points[:, c] += bound                                    # x_c + u_c >= x_c + bound
        values, size = points[:, c], np.ptp(msh.geometry.x, axis=0).max()
    flat = float(values.mean()) if np.ptp(values) <= FLAT_TOLERANCE * max(size, np.finfo(float).tiny) else None
    axis = "u" if c is None else "xyz"[c]
    if flat is not None:
        note = f"grey: the obstacle {axis} = {flat:.4g}"
    else:
        note = f"grey: the obstacle through its {len(verts)} points"
    if moving:
        note += f" at t = {float(time):.4g} (it moves)"
    return {"component": None if c is None else int(c), "flat": flat, "points": points.tolist(), "note": note,
            "moving": bool(moving)}
