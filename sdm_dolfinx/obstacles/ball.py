"""The ball (a disc in 2-D), or with ``inside=True`` the cavity around it (a bowl)."""
from __future__ import annotations

from typing import Any

import numpy as np

from sdm_dolfinx.obstacles.base import Array, Obstacle, flag, number, vector


def radial(d: Array, radius: float, inside: bool, centre_normal: Array,
           off: Any = True) -> tuple[Array, Array]:
    """(phi, normal) for the distance |d| to a centre (point or axis): sign (|d| - R), sign d/|d|, sign = -1
    when ``inside``; ``centre_normal`` where |d| == 0 (or not ``off``)."""
    r = np.linalg.norm(d, axis=0)
    n = np.repeat(centre_normal[:, None], d.shape[1], axis=1)
    ok = (r > 0) & off
    n[:, ok] = d[:, ok] / r[ok]
    sign = -1.0 if inside else 1.0
    return sign * (r - radius), sign * n


def circle(c: Array, radius: float, n: int = 361) -> list[Array]:
    """The circle about (c_x, c_y) in the plane z = 0 as a closed polyline of n points (pictures)."""
    a = np.linspace(0.0, 2.0 * np.pi, n)
    return [np.column_stack([c[0] + radius * np.cos(a), c[1] + radius * np.sin(a), 0.0 * a])]


class Ball(Obstacle):
    """inside=False: the obstacle is the ball |x - c| <= R, phi = |x - c| - R, normal (x - c)/|x - c|
    (e_x at the centre). inside=True: the obstacle is everything outside the ball (the body moves in a
    spherical/circular cavity, a bowl), phi = R - |x - c|, normal -(x - c)/|x - c| (-e_x at the centre).

    Args:
        centre, radius, inside: c (2 numbers (x, y) are (x, y, 0): the disc in 2-D), R > 0, see above.
        motion, motion_velocity, rotation: see :class:`Obstacle`.
    """

    kind = "ball"

    def __init__(self, centre: Any, radius: Any, inside: Any = False, **motion: Any) -> None:
        self.centre = vector(centre, f"{self.kind}: centre")
        self.radius = number(radius, f"{self.kind}: radius")
        self.inside = flag(inside, f"{self.kind}: inside")
        super().__init__(**motion)

    def _distance0(self, y: Array) -> tuple[Array, Array]:
        return radial(y - self.centre[:, None], self.radius, self.inside, np.array([1.0, 0.0, 0.0]))

    @property
    def planar(self) -> bool:
        return bool(self.centre[2] == 0.0)

    def _reference_outline(self, lo: Array, hi: Array) -> list[Array]:
        return circle(self.centre, self.radius)

    def _parameters(self) -> dict[str, Any]:
        return {"centre": self.centre.tolist(), "radius": self.radius, "inside": self.inside}
