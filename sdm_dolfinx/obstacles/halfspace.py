"""The half-space (a half-plane in 2-D): the obstacle is {(x - p).n < 0}, of any orientation."""
from __future__ import annotations

from typing import Any

import numpy as np

from sdm_dolfinx.obstacles.base import Array, Obstacle, vector


class HalfSpace(Obstacle):
    """phi(x) = (x - p).n, normal = n (normalised): the free space is the side n points to.

    Args:
        point: a point p of the boundary plane (line in 2-D).
        normal: its normal n, pointing from the obstacle into the free space (any length but 0).
        motion, motion_velocity, rotation: see :class:`Obstacle`.
    """

    kind = "half-space"

    def __init__(self, point: Any, normal: Any, **motion: Any) -> None:
        self.point = vector(point, f"{self.kind}: point")
        self.normal = vector(normal, f"{self.kind}: normal", unit=True)
        super().__init__(**motion)

    def _distance0(self, y: Array) -> tuple[Array, Array]:
        phi = self.normal @ (y - self.point[:, None])
        return phi, np.repeat(self.normal[:, None], y.shape[1], axis=1)

    @property
    def planar(self) -> bool:
        return bool(self.normal[2] == 0.0)

    def _reference_outline(self, lo: Array, hi: Array) -> list[Array]:
        mid, half = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
        foot = mid - (self.normal @ (mid - self.point)) * self.normal      # mid's projection on the line
        tangent = np.array([-self.normal[1], self.normal[0], 0.0])
        foot[2] = 0.0
        return [np.array([foot - half * tangent, foot + half * tangent])]

    def _parameters(self) -> dict[str, Any]:
        return {"point": self.point.tolist(), "normal": self.normal.tolist()}
