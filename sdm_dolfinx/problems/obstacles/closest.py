"""Closest points on segments and triangles (vectorised over pairs), and the candidate pairs of a
point cloud and a surface mesh found through a KD-tree of the elements' centroids.

Feature codes: 0 the element's interior (a segment's or triangle's), 1 + k its vertex k, 4 + k a
triangle's edge k (from vertex k to vertex (k + 1) % 3).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

INTERIOR, VERTEX, EDGE = 0, 1, 4


def on_segments(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(closest points (m, 3), feature codes (m,)) of the points p (m, 3) on the segments [a, b]."""
    ab = b - a
    t = np.einsum("ij,ij->i", p - a, ab) / np.einsum("ij,ij->i", ab, ab)
    feature = np.where(t <= 0.0, VERTEX, np.where(t >= 1.0, VERTEX + 1, INTERIOR))
    t = np.clip(t, 0.0, 1.0)
    return a + t[:, None] * ab, feature


def on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(closest points (m, 3), feature codes (m,)) of the points p on the triangles (a, b, c):
    Ericson, Real-Time Collision Detection (2005), 5.1.5, each Voronoi region tested in its order
    (the first that holds wins)."""
    def dot(u, v):
        return np.einsum("ij,ij->i", u, v)

    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    q = np.empty_like(p)
    feature = np.full(len(p), -1)
    done = np.zeros(len(p), dtype=bool)

    def take(mask, point, code):
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


class Candidates:
    """The elements that may hold a point's closest point: the element whose centroid is nearest
    (at the distance d0) bounds the distance by d0 (the centroid lies on it), so only elements
    whose centroid is within d0 + (the largest centroid-to-vertex distance) can do better."""

    def __init__(self, points: np.ndarray, cells: np.ndarray) -> None:
        corners = points[cells]                                   # (m, k, 3)
        self.centroids = corners.mean(axis=1)
        self.reach = float(np.linalg.norm(corners - self.centroids[:, None], axis=2).max())
        self.tree = cKDTree(self.centroids)

    def pairs(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(point index, element index) of every candidate pair of the points x (n, 3)."""
        d0, _ = self.tree.query(x)
        radius = d0 * (1 + 1e-12) + self.reach * (1 + 1e-12)      # round-off must not lose the nearest
        lists = self.tree.query_ball_point(x, radius)
        counts = np.fromiter((len(ell) for ell in lists), dtype=np.int64, count=len(lists))
        point = np.repeat(np.arange(len(x)), counts)
        element = np.concatenate([np.asarray(ell, dtype=np.int64) for ell in lists]) if len(x) else \
            np.zeros(0, dtype=np.int64)
        return point, element


def nearest(point: np.ndarray, dist: np.ndarray, n: int) -> np.ndarray:
    """For each of the n points, the index (into the pairs) of its pair of least ``dist``."""
    order = np.lexsort((dist, point))
    first = np.searchsorted(point[order], np.arange(n))
    return order[first]
