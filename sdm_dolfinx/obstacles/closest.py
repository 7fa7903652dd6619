"""Closest points on segments and triangles (vectorised over pairs), and on a mesh of them. Feature codes:
0 the element's interior, 1 + k its vertex k, 4 + k a triangle's edge k (vertex k to vertex (k + 1) % 3).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from sdm_dolfinx.obstacles.base import Array

INTERIOR, VERTEX, EDGE = 0, 1, 4


def on_segments(p: Array, a: Array, b: Array) -> tuple[Array, Array]:
    """(closest points (m, 3), feature codes (m,)) of the points p (m, 3) on the segments [a, b]."""
    ab = b - a
    t = np.einsum("ij,ij->i", p - a, ab) / np.einsum("ij,ij->i", ab, ab)
    feature = np.where(t <= 0.0, VERTEX, np.where(t >= 1.0, VERTEX + 1, INTERIOR))
    t = np.clip(t, 0.0, 1.0)
    return a + t[:, None] * ab, feature


def on_triangles(p: Array, a: Array, b: Array, c: Array) -> tuple[Array, Array]:
    """(closest points (m, 3), feature codes (m,)) of the points p on the triangles (a, b, c):
    Ericson, Real-Time Collision Detection (2005), 5.1.5, each Voronoi region tested in its order
    (the first that holds wins)."""
    def dot(u: Array, v: Array) -> Any:
        return np.einsum("ij,ij->i", u, v)

    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    q = np.empty_like(p)
    feature = np.full(len(p), -1)
    done = np.zeros(len(p), dtype=bool)

    def take(mask: Array, point: Array, code: int) -> None:
        m = mask & ~done
        q[m] = point[m] if point.ndim == 2 else point
        feature[m] = code
        done[m] = True

    with np.errstate(divide="ignore", invalid="ignore"):
        take((d1 <= 0) & (d2 <= 0), a, VERTEX)
        take((d3 >= 0) & (d4 <= d3), b, VERTEX + 1)
        take((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + (d1 / (d1 - d3))[:, None] * ab, EDGE)
        take((d6 >= 0) & (d5 <= d6), c, VERTEX + 2)
        take((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + (d2 / (d2 - d6))[:, None] * ac, EDGE + 2)
        take((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
             b + ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None] * (c - b), EDGE + 1)
        denom = va + vb + vc
        take(np.ones(len(p), dtype=bool), a + (vb / denom)[:, None] * ab + (vc / denom)[:, None] * ac, INTERIOR)
    return q, feature


class Closest:
    """Closest points on a mesh of segments or triangles: the distance u to the element of the nearest
    centroid bounds it; an element can do better only if its centroid is within u + (the largest centroid-
    to-vertex distance) (a KD-tree query) and (triangles) its disc (in its plane, about its centroid, through
    its farthest vertex) is within u (this prunes a far point's many near-equidistant elements)."""

    def __init__(self, points: Array, cells: Array, normals: Array) -> None:
        self.points, self.cells, self.normals = points, cells, normals
        corners = points[cells]                                   # (m, k, 3)
        self.centroids = corners.mean(axis=1)
        self.radii = np.linalg.norm(corners - self.centroids[:, None], axis=2).max(axis=1)
        self.tree = cKDTree(self.centroids)
        self.extent = float(np.abs(points).max())

    def project(self, x: Array, element: Array) -> tuple[Array, Array, Array]:
        """(closest points, feature codes, distances) of the points x (m, 3) on the elements (m,)."""
        corners = [self.points[self.cells[element, k]] for k in range(self.cells.shape[1])]
        q, feature = on_segments(x, *corners) if len(corners) == 2 else on_triangles(x, *corners)
        return q, feature, np.linalg.norm(x - q, axis=1)

    def __call__(self, x: Array) -> tuple[Array, Array, Array, Array]:
        """(closest points q (n, 3), feature codes, elements, distances) of the points x (n, 3)."""
        _, first = self.tree.query(x)
        slack = 1e-12 * (np.abs(x).max(axis=1) + self.extent)            # round-off must not lose the nearest
        upper = self.project(x, first)[2] + slack
        lists = self.tree.query_ball_point(x, upper + self.radii.max() + slack)
        point = np.repeat(np.arange(len(x)), [len(ell) for ell in lists])
        element = np.fromiter((e for ell in lists for e in ell), dtype=np.int64, count=len(point))
        if self.cells.shape[1] == 3:
            r = x[point] - self.centroids[element]
            h = np.einsum("ij,ij->i", r, self.normals[element])
            rho = np.sqrt(np.maximum(np.einsum("ij,ij->i", r, r) - h * h, 0.0))
            lower = np.sqrt(h * h + np.maximum(rho - self.radii[element], 0.0) ** 2)
            keep = (lower <= upper[point] + slack[point]) | (element == first[point])
            point, element = point[keep], element[keep]
        q, feature, dist = self.project(x[point], element)
        order = np.lexsort((dist, point))                            # for each point, its pair of least dist
        best = order[np.searchsorted(point[order], np.arange(len(x)))]
        return q[best], feature[best], element[best], dist[best]
