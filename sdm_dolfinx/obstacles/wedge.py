"""The wedge: the convex region {(x - a).n1 <= 0 and (x - a).n2 <= 0} (a corner in 2-D, an edge along
n1 x n2 in 3-D), with its exact signed distance."""
from __future__ import annotations

from typing import Any

import numpy as np

from sdm_dolfinx.obstacles.base import Array, Obstacle, ObstacleError, vector

#: |n1 x n2| below this (unit normals): parallel or opposite, refused (no edge)
PARALLEL_TOL = 1e-8


class Wedge(Obstacle):
    """Exact signed distance to the convex set C = {d1 <= 0, d2 <= 0}, d_i = (x - a).n_i (n_i
    normalised, pointing out of the obstacle).

    Inside C: phi = max(d1, d2) (the distance to the nearer face, negative), normal the n_i of the
    larger d_i; on the bisector (d1 == d2) the normalised n1 + n2. Outside C: phi the Euclidean
    distance to C, i.e. to the nearest of face 1 (the foot x - d1 n1 when it lies in C), face 2, and
    the edge (the apex line a + s e, e = n1 x n2 / |n1 x n2|; the apex in 2-D), normal (x - q)/phi
    for q that nearest point (on the edge itself, a tie inside: the normalised n1 + n2).

    Args:
        apex, normal1, normal2: a point of the edge (the corner in 2-D); the faces' outward normals (any
            length but 0, not parallel or opposite). motion, motion_velocity, rotation: see :class:`Obstacle`.
    """

    kind = "wedge"

    def __init__(self, apex: Any, normal1: Any, normal2: Any, **motion: Any) -> None:
        self.apex = vector(apex, f"{self.kind}: apex")
        self.n1 = vector(normal1, f"{self.kind}: normal1", unit=True)
        self.n2 = vector(normal2, f"{self.kind}: normal2", unit=True)
        e = np.cross(self.n1, self.n2)
        if np.linalg.norm(e) < PARALLEL_TOL:
            raise ObstacleError(f"{self.kind}: normal1 {self.n1.tolist()} and normal2 {self.n2.tolist()} are "
                                f"parallel or opposite (a half-space or a slab, not a wedge)")
        self.edge = e / np.linalg.norm(e)
        mean = self.n1 + self.n2
        self._mean = mean / np.linalg.norm(mean)
        super().__init__(**motion)

    def _distance0(self, y: Array) -> tuple[Array, Array]:
        r = y - self.apex[:, None]
        d1, d2 = self.n1 @ r, self.n2 @ r
        c = float(self.n1 @ self.n2)
        phi = np.maximum(d1, d2)
        normal = np.where(d1 > d2, self.n1[:, None], self.n2[:, None])
        normal[:, d1 == d2] = self._mean[:, None]
        out = phi > 0.0
        if np.any(out):
            ro, e1, e2 = r[:, out], d1[out], d2[out]
            radial = ro - np.outer(self.edge, self.edge @ ro)          # to the edge line
            cand = np.vstack([np.where((e1 > 0) & (e2 - c * e1 <= 0), e1, np.inf),     # face 1's foot in C
                              np.where((e2 > 0) & (e1 - c * e2 <= 0), e2, np.inf),     # face 2's foot in C
                              np.linalg.norm(radial, axis=0)])                          # the edge
            which = np.argmin(cand, axis=0)
            dist = cand[which, np.arange(cand.shape[1])]
            n = np.where(which == 0, self.n1[:, None], self.n2[:, None])
            edge = which == 2
            n[:, edge] = radial[:, edge] / dist[edge]                    # > 0: x is outside C
            phi[out], normal[:, out] = dist, n
        return phi, normal

    @property
    def planar(self) -> bool:
        return bool(self.n1[2] == 0.0 and self.n2[2] == 0.0)

    def _reference_outline(self, lo: Array, hi: Array) -> list[Array]:
        a = self.apex * [1.0, 1.0, 0.0]
        reach = float(np.linalg.norm(hi - lo) + np.linalg.norm((lo + hi) / 2 - a))
        # along the faces away from the edge: (n1 x e).n2 = (e x n2).n1 = -|n1 x n2| < 0
        return [np.array([a + reach * np.cross(self.n1, self.edge), a, a + reach * np.cross(self.edge, self.n2)])]

    def _parameters(self) -> dict[str, Any]:
        return {"apex": self.apex.tolist(), "normal1": self.n1.tolist(), "normal2": self.n2.tolist()}
