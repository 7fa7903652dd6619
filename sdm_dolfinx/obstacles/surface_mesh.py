"""An obstacle whose surface is a mesh read from a gmsh .msh file: 2-node lines in 2-D (in the plane
z = 0), 3-node triangles in 3-D; the signed distance by closest-point projection (a KD-tree prefilter).

Orientation convention (element normals point into the free space): a line from node a to node b has
the normal (t_y, -t_x)/|t|, t = b - a (the obstacle on its LEFT: a closed curve around a solid runs
counter-clockwise); a triangle (a, b, c) has (b - a) x (c - a) normalised (counter-clockwise seen from the
free space: gmsh's outward boundary of a volume). ``side`` says where the body may be: "outside" (default)
or "inside" a closed curve/surface (each component re-oriented from the sign of its enclosed area/volume,
so the file's orientation does not matter; components must not be nested), or "normals": the side the
element normals point to, as the file orients them (closed or not; an open sheet's distance is two-sided).

The sign of phi is that of (x - q).N, q the closest point, N the pseudo-normal of its feature (element:
its normal; 2-D vertex, 3-D edge: the sum of the adjacent unit normals; 3-D vertex: their angle-weighted
sum; Baerentzen & Aanaes 2005: right at convex and concave corners). normal = grad phi = sign (x - q)/|phi|
(the element normal if q is inside an element; the unit pseudo-normal if |phi| <= 1e-12 the mesh's size).
"""
from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any, Optional

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from sdm_dolfinx.obstacles import closest, msh
from sdm_dolfinx.obstacles.base import Array, Obstacle, ObstacleError

SIDES = ("outside", "inside", "normals")
#: gmsh's other 2-D element types (quadrangles, curved triangles) and curved lines: refused, not ignored
OTHER_SURFACE = (3, 9, 10, 16, 20, 21, 22, 23, 24, 25)
OTHER_LINES = (8, 26, 27, 28)


def _unit_rows(v: Array) -> Array:
    n = np.linalg.norm(v, axis=1)
    return np.asarray(v / np.where(n > 0, n, 1.0)[:, None])


def element_normals(points: Array, cells: Array) -> tuple[Array, Array]:
    """(unit normals (m, 3), sizes (m,): lengths or twice the areas) by the orientation convention."""
    t = points[cells[:, 1]] - points[cells[:, 0]]
    n = np.column_stack([t[:, 1], -t[:, 0], 0 * t[:, 0]]) if cells.shape[1] == 2 else \
        np.cross(t, points[cells[:, 2]] - points[cells[:, 0]])
    return _unit_rows(n), np.linalg.norm(n, axis=1)


def _edges(cells: Array) -> Array:
    """The directed edges (3m, 2) of triangles, edge k of cell i at row 3 i + k."""
    return np.asarray(np.stack([cells, np.roll(cells, -1, axis=1)], axis=2).reshape(-1, 2))


def check_topology(cells: Array, closed: bool, where: str) -> None:
    """Consistent orientation (a manifold curve/surface), and closedness when ``closed``: each vertex
    (2-D) or edge (3-D) is passed once in each direction (once in all, at an open boundary)."""
    if cells.shape[1] == 2:                            # a vertex "forward" where a line starts, "back" where one ends
        passes = [(int(v), k) for k in range(2) for v in cells[:, k]]
    else:
        passes = [tuple(e) for e in _edges(cells).tolist()]
    seen = set(passes)
    if len(seen) != len(passes):
        raise ObstacleError(f"{where}: the elements are not consistently oriented, or the curve/surface branches")
    if closed and any((b, a) not in seen if cells.shape[1] == 3 else (a, 1 - b) not in seen for a, b in seen):
        raise ObstacleError(f"{where}: the curve/surface is not closed (side 'outside'/'inside' need it closed; "
                            f"side='normals' takes an open one)")


def orient(points: Array, cells: Array, side: str) -> Array:
    """``cells`` with each connected component's orientation chosen so that its normals point into
    the free space of ``side`` (the sign of its enclosed area/volume)."""
    rows = np.repeat(np.arange(len(cells)), cells.shape[1])
    graph = coo_matrix((np.ones(rows.size), (rows, cells.ravel())), shape=(len(cells), len(points))).tocsr()
    _, label = connected_components(graph @ graph.T, directed=False)
    a, b = points[cells[:, 0]], points[cells[:, 1]]
    if cells.shape[1] == 2:
        signed = 0.5 * (a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])             # the enclosed area
    else:
        signed = np.einsum("ij,ij->i", a, np.cross(b, points[cells[:, 2]])) / 6.0     # the enclosed volume
    per = np.bincount(label, weights=signed)
    want = 1.0 if side == "outside" else -1.0
    flip = per[label] * want < 0
    out = cells.copy()
    out[flip] = out[flip][:, ::-1]
    return out


def pseudo_normals(points: Array, cells: Array,
                   normals: Array) -> tuple[Array, Optional[Array]]:
    """(vertex pseudo-normals (N, 3), edge pseudo-normals per triangle edge (m, 3, 3) or None)."""
    vertex = np.zeros_like(points)
    if cells.shape[1] == 2:
        np.add.at(vertex, cells.ravel(), np.repeat(normals, 2, axis=0))       # row i of cells.ravel(): cell i // 2
        return vertex, None
    for k in range(3):                                              # angle-weighted at the vertices
        u = points[cells[:, (k + 1) % 3]] - points[cells[:, k]]
        w = points[cells[:, (k + 2) % 3]] - points[cells[:, k]]
        cos = np.einsum("ij,ij->i", _unit_rows(u), _unit_rows(w))
        np.add.at(vertex, cells[:, k], np.arccos(np.clip(cos, -1.0, 1.0))[:, None] * normals)
    e = np.sort(_edges(cells), axis=1)
    _, edge_id = np.unique(e, axis=0, return_inverse=True)
    edge_id = edge_id.ravel()
    summed = np.zeros((edge_id.max() + 1, 3))
    np.add.at(summed, edge_id, np.repeat(normals, 3, axis=0))
    return vertex, summed[edge_id].reshape(len(cells), 3, 3)


def select(points: Array, cells: dict[int, Array], dim: Optional[int], where: str) -> tuple[int, Array]:
    """(dim, the cells of that dimension): triangles in 3-D, lines in 2-D (``dim`` None: triangles if
    any, else lines; triangles all in the plane z = 0 are a 2-D domain, refused without ``dim``)."""
    if dim not in (None, 2, 3) or isinstance(dim, bool):
        raise ObstacleError(f"{where}: dim must be None, 2 or 3, got {dim!r}")
    tri = cells.get(msh.TRIANGLE)
    if dim is None and tri is not None and np.all(points[np.unique(tri), 2] == 0.0):
        raise ObstacleError(f"{where}: the triangles lie in the plane z = 0 (a 2-D domain?): pass dim=2 to use its "
                            f"lines or dim=3 for the triangles")
    dim = dim or (3 if tri is not None else 2)
    name = {2: "line", 3: "triangle"}[dim]
    found = [t for t in (OTHER_SURFACE if dim == 3 else OTHER_LINES) if t in cells]
    chosen = cells.get(msh.TRIANGLE if dim == 3 else msh.LINE, np.zeros((0, dim), dtype=np.int64))
    if found or len(chosen) == 0:
        raise ObstacleError(f"{where}: " + (f"elements of gmsh type(s) {found} are not read" if found else
                                            f"no {name} elements") + f" (a {dim}-D surface: {dim}-node {name}s)")
    if dim == 2 and np.any(points[np.unique(chosen), 2] != 0.0):
        raise ObstacleError(f"{where}: a 2-D surface mesh (lines) must lie in the plane z = 0")
    return dim, chosen


class SurfaceMesh(Obstacle):
    """The obstacle bounded by the lines (2-D) or triangles (3-D) of a gmsh ASCII .msh file (the module
    docstring says the orientation convention and ``side``).

    Args:
        path, side: the .msh file (formats 2.2 or 4.1, ASCII); "outside" (default), "inside" or "normals".
        dim: 2 (lines), 3 (triangles) or None (triangles if any, else lines).
        motion, motion_velocity, rotation: see :class:`Obstacle`.
    """

    kind = "surface-mesh"

    def __init__(self, path: Any, side: str = "outside", dim: Optional[int] = None, **motion: Any) -> None:
        where = f"{self.kind} {str(path)!r}"
        if side not in SIDES:
            raise ObstacleError(f"{where}: side must be one of {', '.join(SIDES)}, got {side!r}")
        self.path, self.side = str(Path(path).resolve()), side
        points, cells = msh.read(path)
        self.sha256 = hashlib.sha256(Path(path).read_bytes()).hexdigest()      # which file, for run.json
        self.dim, chosen = select(points, cells, dim, where)
        used, chosen = np.unique(chosen, return_inverse=True)
        self.points, self.cells = points[used], chosen.reshape(-1, self.dim)
        self.size = float(np.linalg.norm(self.points.max(axis=0) - self.points.min(axis=0)))
        bad = int(np.sum(element_normals(self.points, self.cells)[1] <= 1e-14 * self.size ** (self.dim - 1)))
        if bad:
            raise ObstacleError(f"{where}: {bad} degenerate element(s) (zero length or area)")
        check_topology(self.cells, side != "normals", where)
        if side != "normals":
            self.cells = orient(self.points, self.cells, side)
        self.normals, _ = element_normals(self.points, self.cells)
        self.vertex_normals, self.edge_normals = pseudo_normals(self.points, self.cells, self.normals)
        self._closest = closest.Closest(self.points, self.cells, self.normals)
        super().__init__(**motion)

    def _distance0(self, y: Array) -> tuple[Array, Array]:
        x = y.T
        q, feature, element, dist = self._closest(x)
        pseudo = self.normals[element].copy()                       # interior: the element normal
        at_vertex = (feature >= closest.VERTEX) & (feature < closest.EDGE)
        pseudo[at_vertex] = self.vertex_normals[self.cells[element[at_vertex], feature[at_vertex] - closest.VERTEX]]
        if self.edge_normals is not None:
            at_edge = feature >= closest.EDGE
            pseudo[at_edge] = self.edge_normals[element[at_edge], feature[at_edge] - closest.EDGE]
        r = x - q
        sign = np.where(np.einsum("ij,ij->i", r, pseudo) < 0, -1.0, 1.0)
        normal = sign[:, None] * r / np.where(dist > 0, dist, 1.0)[:, None]
        interior = feature == closest.INTERIOR
        normal[interior] = self.normals[element[interior]]           # grad phi there, on both sides
        tiny = (dist <= 1e-12 * self.size) & ~interior
        normal[tiny] = _unit_rows(pseudo[tiny])
        return sign * dist, normal.T

    @property
    def planar(self) -> bool:
        return self.dim == 2

    def _reference_outline(self, lo: Array, hi: Array) -> list[Array]:
        return list(self.points[self.cells])                        # each line a polyline of 2 points

    def _parameters(self) -> dict[str, Any]:
        return {"path": self.path, "side": self.side, "dim": self.dim, "elements": int(len(self.cells)),
                "sha256": self.sha256}
