"""The circular cylinder (3-D), or with ``inside=True`` the cylindrical cavity (a pipe)."""
from __future__ import annotations

from typing import Any

import numpy as np

from sdm_dolfinx.problems.obstacles.ball import circle, radial
from sdm_dolfinx.problems.obstacles.base import Obstacle, ObstacleError, flag, number, vector


#: a point within this relative distance of the axis (round-off of the projection) is on it
ON_AXIS = 1e-14


class Cylinder(Obstacle):
    """The distance to the axis line {p + s a}: r = |(x - p) - ((x - p).a) a|. inside=False: the
    obstacle is the solid cylinder r <= R, phi = r - R, normal the radial unit vector; inside=True:
    the obstacle is everything outside it, phi = R - r, normal minus the radial one. On the axis the
    normal is (for inside=False; its opposite for inside=True) the unit vector a x e_k normalised, e_k
    the coordinate axis least aligned with a (on it: r <= 1e-14 (|x - p| + R), the projection's round-off).

    Args:
        point: p, a point of the axis (3 numbers).
        axis: a, the axis direction (3 numbers, any length but 0). In 2-D use a ball (a disc).
        radius: R > 0.
        inside: see above.
        motion, motion_velocity, rotation: see :class:`Obstacle`.
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

    def _distance0(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        full = y - self.point[:, None]
        d = full - np.outer(self.axis, self.axis @ full)
        off = np.linalg.norm(d, axis=0) > ON_AXIS * (np.linalg.norm(full, axis=0) + self.radius)   # beyond round-off
        return radial(d, self.radius, self.inside, self._on_axis, off)

    @property
    def planar(self) -> bool:
        return bool(self.axis[0] == 0.0 and self.axis[1] == 0.0)

    def _reference_outline(self, lo: np.ndarray, hi: np.ndarray) -> list[np.ndarray]:
        return circle(self.point, self.radius)

    def _parameters(self) -> dict[str, Any]:
        return {"point": self.point.tolist(), "axis": self.axis.tolist(), "radius": self.radius,
                "inside": self.inside}
