"""The circular cylinder (3-D), or with ``inside=True`` the cylindrical cavity (a pipe)."""
from __future__ import annotations

from typing import Any

import numpy as np

from sdm_dolfinx.obstacles.ball import circle, radial
from sdm_dolfinx.obstacles.base import Array, Obstacle, ObstacleError, flag, number, vector

#: a point within this relative distance of the axis (round-off of the projection) is on it
ON_AXIS = 1e-14


class Cylinder(Obstacle):
    """r = |(x - p) - ((x - p).a) a| the distance to the axis line: inside=False, the obstacle is the solid
    cylinder r <= R, phi = r - R, normal the radial unit vector; inside=True (a pipe), phi = R - r, normal
    its opposite. On the axis (r <= 1e-14 (|x - p| + R): round-off) the normal is (minus, inside) a x e_k
    normalised, e_k the coordinate axis least aligned with a.

    Args:
        point, axis: p a point of the axis, a its direction (3 numbers each; in 2-D a ball is the disc).
        radius, inside: R > 0 and see above; motion, motion_velocity, rotation: see :class:`Obstacle`.
    """

    kind = "cylinder"

    def __init__(self, point: Any, axis: Any, radius: Any, inside: Any = False, **motion: Any) -> None:
        if np.shape(point) != (3,) or np.shape(axis) != (3,):
            raise ObstacleError(f"{self.kind}: point and axis must be vectors of 3 numbers (a cylinder is 3-D; "
                                f"in 2-D a ball is the disc), got {point!r}, {axis!r}")
        self.point = vector(point, f"{self.kind}: point")
        self.axis = vector(axis, f"{self.kind}: axis", unit=True)
        self.radius = number(radius, f"{self.kind}: radius")
        self.inside = flag(inside, f"{self.kind}: inside")
        k = int(np.argmin(np.abs(self.axis)))
        off = np.cross(self.axis, np.eye(3)[k])
        self._on_axis = off / np.linalg.norm(off)
        super().__init__(**motion)

    def _distance0(self, y: Array) -> tuple[Array, Array]:
        full = y - self.point[:, None]
        d = full - np.outer(self.axis, self.axis @ full)
        off = np.linalg.norm(d, axis=0) > ON_AXIS * (np.linalg.norm(full, axis=0) + self.radius)   # beyond round-off
        return radial(d, self.radius, self.inside, self._on_axis, off)

    @property
    def planar(self) -> bool:
        return bool(self.axis[0] == 0.0 and self.axis[1] == 0.0)

    def _reference_outline(self, lo: Array, hi: Array) -> list[Array]:
        return circle(self.point, self.radius)

    def _parameters(self) -> dict[str, Any]:
        return {"point": self.point.tolist(), "axis": self.axis.tolist(), "radius": self.radius,
                "inside": self.inside}
