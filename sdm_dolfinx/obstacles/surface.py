"""The obstacles' surfaces as a mesh at a time t, clipped to a box: what pictures draw and what the run
folder's ``obstacles.xdmf`` holds (sdm_dolfinx/io/obstacle_xdmf.py). Geometry only.

2-D (a box without z extent): the segments of :meth:`Obstacle.outline` (its section z = 0). 3-D: a
triangulated surface, built at the declared position about the box's pre-image and moved with the
obstacle's rigid motion, then clipped to the box (Sutherland-Hodgman on each triangle that crosses it):
a half-space's plane (a quad), a ball's sphere (a UV sphere of ``SPHERE`` quads), a cylinder's tube
(``SPHERE[0]`` quads round, straight along its axis), a wedge's two faces (quads from its edge), a
surface mesh's triangles. A sphere's or cylinder's facets are flat: their vertices lie on the surface,
their centres up to R (1 - cos(pi / SPHERE[0])) inside it (2e-3 R). What is not drawn (a shape this
module does not know, a surface mesh of lines in a 3-D box, a shape that is not planar in 2-D) is named
in ``missing``.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from sdm_dolfinx.obstacles.ball import Ball
from sdm_dolfinx.obstacles.base import Array, Obstacle, ObstacleError, vector
from sdm_dolfinx.obstacles.cylinder import Cylinder
from sdm_dolfinx.obstacles.halfspace import HalfSpace
from sdm_dolfinx.obstacles.surface_mesh import SurfaceMesh
from sdm_dolfinx.obstacles.wedge import Wedge

#: (around, from pole to pole) quads of a ball's sphere; a cylinder has SPHERE[0] around
SPHERE = (48, 24)


def enlarged_box(lo: Any, hi: Any, factor: float) -> tuple[Array, Array]:
    """The box about the middle of [lo, hi] whose half sides are ``factor`` times its largest side (each
    side of a 3-D box; x and y of a 2-D one, whose z extent stays 0)."""
    lo, hi = vector(lo, "box: lo"), vector(hi, "box: hi")
    mid, half = (lo + hi) / 2, factor * float(np.max(hi - lo))
    span = np.array([half, half, half if hi[2] > lo[2] else 0.0])
    return mid - span, mid + span


def _frame(n: Array) -> tuple[Array, Array]:
    """Two unit vectors orthogonal to the unit n and to each other."""
    k = int(np.argmin(np.abs(n)))
    u = np.cross(n, np.eye(3)[k])
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def _grid(corner: Array, du: Array, dv: Array, nu: int, nv: int, wrap_u: bool = False) -> tuple[Array, Array]:
    """Points corner + (i/nu) du(i) + (j/nv) dv and the triangles of the nu x nv quads (du given as an
    array of nu (+1) points offsets when it is not straight)."""
    iu = np.arange(nu if wrap_u else nu + 1)
    iv = np.arange(nv + 1)
    offs_u = du if du.ndim == 2 else np.outer(iu / nu, du)
    pts = corner + offs_u[:, None, :] + np.outer(iv / nv, dv)[None, :, :]
    cols = len(iv)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * cols + j
    b = ((i + 1) % len(iu)) * cols + j
    tri = np.concatenate([np.stack([a, b, b + 1], -1).reshape(-1, 3), np.stack([a, b + 1, a + 1], -1).reshape(-1, 3)])
    return pts.reshape(-1, 3), tri


def _sphere(c: Array, r: float) -> tuple[Array, Array]:
    na, nb = SPHERE
    th, ph = np.meshgrid(np.linspace(0, 2 * np.pi, na, endpoint=False), np.linspace(0, np.pi, nb + 1), indexing="ij")
    pts = c + r * np.stack([np.sin(ph) * np.cos(th), np.sin(ph) * np.sin(th), np.cos(ph)], -1).reshape(-1, 3)
    _, tri = _grid(np.zeros(3), np.zeros((na, 3)), np.zeros(3), na, nb, wrap_u=True)
    area = np.linalg.norm(np.cross(pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]]), axis=1)
    return pts, tri[area > 1e-12 * r * r]                    # the poles' degenerate triangles left out


def _reference_surface(ob: Obstacle, mid: Array, reach: float) -> tuple[Array, Array] | None:
    """The declared surface (points (n, 3), triangles (m, 3)) covering the ball of radius ``reach`` about
    ``mid`` (declared position), or None for a shape drawn nowhere."""
    if isinstance(ob, HalfSpace):
        foot = mid - float(ob.normal @ (mid - ob.point)) * ob.normal
        u, v = _frame(ob.normal)
        return _grid(foot - reach * (u + v), 2 * reach * u, 2 * reach * v, 1, 1)
    if isinstance(ob, Ball):
        return _sphere(ob.centre, ob.radius)
    if isinstance(ob, Cylinder):
        u, v = _frame(ob.axis)
        foot = ob.point + float(ob.axis @ (mid - ob.point)) * ob.axis
        th = np.linspace(0, 2 * np.pi, SPHERE[0], endpoint=False)
        ring = ob.radius * (np.outer(np.cos(th), u) + np.outer(np.sin(th), v))
        return _grid(foot - reach * ob.axis, ring, 2 * reach * ob.axis, SPHERE[0], 1, wrap_u=True)
    if isinstance(ob, Wedge):
        foot = ob.apex + float(ob.edge @ (mid - ob.apex)) * ob.edge
        reach += float(np.linalg.norm(mid - foot))
        faces = [_grid(foot - reach * ob.edge, 2 * reach * ob.edge, reach * w, 1, 1)
                 for w in (np.cross(ob.n1, ob.edge), np.cross(ob.edge, ob.n2))]
        return np.vstack([faces[0][0], faces[1][0]]), np.vstack([faces[0][1], faces[1][1] + len(faces[0][0])])
    if isinstance(ob, SurfaceMesh) and ob.dim == 3:
        return ob.points.copy(), ob.cells.copy()
    return None


def clip_triangles(tri: Array, lo: Array, hi: Array) -> Array:
    """The parts of the triangles ``tri`` (m, 3, 3) inside the box [lo, hi], as triangles (k, 3, 3)."""
    inside = np.all((tri >= lo) & (tri <= hi), axis=(1, 2))
    away = np.zeros(len(tri), dtype=bool)
    for k in range(3):
        away |= np.all(tri[:, :, k] < lo[k], axis=1) | np.all(tri[:, :, k] > hi[k], axis=1)
    out = [tri[inside]]
    for t in tri[~inside & ~away]:
        poly = list(t)
        for k in range(3):
            for sign, bound in ((1.0, lo[k]), (-1.0, hi[k])):       # keep sign (x_k - bound) >= 0
                if not poly:
                    break
                new = []
                for i, p in enumerate(poly):
                    q = poly[(i + 1) % len(poly)]
                    dp, dq = sign * (p[k] - bound), sign * (q[k] - bound)
                    if dp >= 0:
                        new.append(p)
                    if (dp >= 0) != (dq >= 0):
                        x = p + (dp / (dp - dq)) * (q - p)
                        x[k] = bound                               # exactly on the box's face
                        new.append(x)
                poly = new
        if len(poly) >= 3:
            out.append(np.array([[poly[0], poly[i], poly[i + 1]] for i in range(1, len(poly) - 1)]))
    return np.concatenate(out) if out else np.zeros((0, 3, 3))


def surface(ob: Obstacle, t: float, box: Sequence[Any]) -> Array | None:
    """The obstacle's surface at the time t within the box ``(lo, hi)``: segments (m, 2, 3) for a box
    without z extent (2-D), triangles (m, 3, 3) otherwise; None when this shape is not drawn there."""
    lo, hi = (vector(b, "surface: the box's corner") for b in box)
    if not np.all(hi >= lo):
        raise ObstacleError(f"surface: the box must have hi >= lo, got {box!r}")
    if hi[2] <= lo[2]:
        if not ob.planar:
            return None
        segs = [np.stack([p[:-1], p[1:]], axis=1) for p in ob.outline(t, (lo, hi)) if len(p) > 1]
        return np.concatenate(segs) if segs else np.zeros((0, 2, 3))
    mid = ob._to_reference(((lo + hi) / 2)[:, None], float(t))[:, 0]
    found = _reference_surface(ob, mid, 0.5 * float(np.linalg.norm(hi - lo)) * (1 + 1e-9))
    if found is None:
        return None
    pts, tri = found
    moved = ob._from_reference(pts.T, float(t)).T
    return clip_triangles(moved[tri], lo, hi)


def mesh(obstacles: Sequence[Obstacle], t: float, box: Sequence[Any]) -> dict[str, Any]:
    """Every obstacle's :func:`surface` at t as one mesh: ``points`` (n, 3), ``cells`` (m, 2 or 3) into
    them, ``which`` (m,) the obstacle's index of each cell, ``missing`` the descriptions of those not drawn."""
    lo, hi = (vector(b, "mesh: the box's corner") for b in box)
    k = 2 if hi[2] <= lo[2] else 3
    pieces, which, missing = [], [], []
    for i, ob in enumerate(obstacles):
        s = surface(ob, t, (lo, hi)) if isinstance(ob, Obstacle) else None
        if s is None:
            missing.append(f"{getattr(ob, 'kind', type(ob).__name__)} (obstacle {i})")
            continue
        pieces.append(s)
        which.append(np.full(len(s), i, dtype=np.int32))
    cells = np.concatenate(pieces) if pieces else np.zeros((0, k, 3))
    points, index = np.unique(cells.reshape(-1, 3), axis=0, return_inverse=True)
    return {"points": points, "cells": index.reshape(-1, k).astype(np.int64),
            "which": np.concatenate(which) if which else np.zeros(0, dtype=np.int32), "missing": missing}
