"""The rigid obstacle: a signed distance phi(x, t) with its unit normal grad phi, and its motion.

Sign convention (every shape): phi > 0 outside the obstacle (the free space, where the body may be),
phi < 0 inside it (penetration), phi = 0 on its surface; the normal grad phi points from the obstacle
into the free space. Points are dolfinx's layout, an array (3, n); a 2-D problem has x[2] == 0 and
wants a :attr:`Obstacle.planar` obstacle (its normals on the plane z = 0 lie in that plane).

Motion (rigid): a translation s(t) (``motion``, a callable t -> (3,)) and optionally a rotation about the
axis parallel to z through ``centre`` at the angular velocity ``omega`` (``rotation=(centre, omega)``, a
cam). The declared obstacle's point X (s = 0, angle 0) is at x(t) = s(t) + c + R(omega t) (X - c), so
phi(x, t) = phi_0(c + R(-omega t) (x - s(t) - c)) and normal(x, t) = R(omega t) normal_0(...); s(0) need
not be 0. The velocity of the obstacle's material point at x is s'(t) + omega e_z x (x - s(t) - c), s'
the given ``motion_velocity`` or the central difference (s(t + h) - s(t - h)) / (2 h), h = 1e-6 max(1, |t|)
(error O(h^2 |s'''|) plus round-off O(1e-10 |s|)).
"""
from __future__ import annotations

import math
from typing import Any, Callable, Optional, Sequence

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.errors import ProblemInputError

#: the arrays of this package (points (3, n), normals, cells, ...)
Array = npt.NDArray[Any]

#: the relative step of the central difference of s(t) when no motion_velocity is given
FD_STEP = 1e-6


class ObstacleError(ProblemInputError):
    """An obstacle's parameters refused (one line)."""


def vector(value: Any, what: str, unit: bool = False) -> Array:
    """``value`` as a finite (3,) float array (a 2-vector gets z = 0); ``unit``: normalised, not zero."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        v = np.zeros(0)
    if v.shape not in ((2,), (3,)) or not np.all(np.isfinite(v)):
        raise ObstacleError(f"{what} must be a finite vector of 2 or 3 numbers, got {value!r}")
    v = np.append(v, 0.0) if v.shape == (2,) else v.copy()
    if unit and not np.any(v):
        raise ObstacleError(f"{what} must not be the zero vector")
    return v / np.linalg.norm(v) if unit else v


def number(value: Any, what: str, positive: bool = True) -> float:
    """``value`` as a finite float (> 0 when ``positive``)."""
    try:
        r = float(value)
    except (TypeError, ValueError):
        r = math.nan
    if not (math.isfinite(r) and (r > 0.0 or not positive)) or isinstance(value, (bool, np.bool_, str)):
        raise ObstacleError(f"{what} must be a finite number{' > 0' if positive else ''}, got {value!r}")
    return r


def flag(value: Any, what: str) -> bool:
    """A bool (True/False only: 0, 1 or a string would be a guess)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ObstacleError(f"{what} must be True or False, got {value!r}")
    return bool(value)


def points(x: Any) -> Array:
    """The points ``x`` as a finite float array (3, n)."""
    a: Array = np.asarray(x, dtype=float)
    if a.ndim != 2 or a.shape[0] != 3 or not np.all(np.isfinite(a)):
        raise ObstacleError(f"obstacle points must be a finite array (3, n) (dolfinx's layout), got shape {a.shape}")
    return a


def _rotate(v: Array, angle: float) -> Array:
    """v (3, n) rotated by ``angle`` about e_z."""
    c, s = math.cos(angle), math.sin(angle)
    return np.vstack([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


class Obstacle:
    """A rigid obstacle: a subclass gives :meth:`_distance0` (phi and normal at the declared position),
    :meth:`_parameters` and (2-D pictures) :meth:`_reference_outline`; this class adds the motion: ``motion``
    None or a callable t -> (3,) (or (2,)) translation s(t), ``motion_velocity`` an optional callable giving
    s'(t), ``rotation`` an optional (centre, omega), omega in rad per time unit, counter-clockwise."""

    kind: str = "obstacle"

    def __init__(self, motion: Optional[Callable[[float], Any]] = None,
                 motion_velocity: Optional[Callable[[float], Any]] = None,
                 rotation: Optional[Sequence[Any]] = None, **unknown: Any) -> None:
        if unknown:     # a misspelt parameter: one line naming what the shape takes (not Python's TypeError)
            import inspect
            own = [n for n in inspect.signature(type(self).__init__).parameters if n not in ("self", "motion")]
            takes = [n for n in own if n not in ("unknown",)] + ["motion", "motion_velocity", "rotation"]
            raise ObstacleError(f"{self.kind}: unknown parameter(s) {', '.join(map(repr, unknown))}; takes "
                                f"{', '.join(dict.fromkeys(takes))}")
        for name, f in (("motion", motion), ("motion_velocity", motion_velocity)):
            if f is not None and not callable(f):
                raise ObstacleError(f"{self.kind}: {name} must be None or a callable t -> (3,), got {f!r}")
        if motion_velocity is not None and motion is None:
            raise ObstacleError(f"{self.kind}: motion_velocity is given without a motion")
        self._motion, self._motion_velocity = motion, motion_velocity
        self._centre, self._omega = np.zeros(3), 0.0
        if rotation is not None:
            if not (isinstance(rotation, (tuple, list)) and len(rotation) == 2):
                raise ObstacleError(f"{self.kind}: rotation must be a pair (centre, omega), got {rotation!r}")
            self._centre = vector(rotation[0], f"{self.kind}: the rotation's centre")
            self._omega = number(rotation[1], f"{self.kind}: the rotation's omega", positive=False)
        self._shift(0.0)                       # a wrong motion callable fails now, not in the run
        self._shift_rate(0.0)

    def _distance0(self, y: Array) -> tuple[Array, Array]:
        """(phi, normal) at the points y (3, n) for the obstacle at its declared position."""
        raise NotImplementedError

    def _reference_outline(self, lo: Array, hi: Array) -> list[Array]:
        """Polylines (k, 3) of the declared surface's section z = 0 crossing the box [lo, hi] (x, y)."""
        return []

    def _parameters(self) -> dict[str, Any]:
        raise NotImplementedError

    @property
    def planar(self) -> bool:
        """True when the obstacle can serve a 2-D problem: its normals on the plane z = 0 lie in it."""
        return False

    @property
    def moves(self) -> bool:
        """True when a motion (translation or rotation) is given."""
        return self._motion is not None or self._omega != 0.0

    def _call(self, name: str, f: Callable[[float], Any], t: float) -> Array:
        """f(t), a user's callable, as a (3,) vector; its failure in one line (the cause chained)."""
        try:
            value = f(t)
        except Exception as exc:
            fd = name == "motion" and t < 0 and self._motion_velocity is None
            hint = " (the central difference evaluates s at t - h: give motion_velocity)" if fd else ""
            raise ObstacleError(f"{self.kind}: {name}({t!r}) raised {type(exc).__name__}: {exc}{hint}") from exc
        return vector(value, f"{self.kind}: {name}({t!r})")

    def _shift(self, t: float) -> Array:
        """s(t) (3,)."""
        return np.zeros(3) if self._motion is None else self._call("motion", self._motion, t)

    def _shift_rate(self, t: float) -> Array:
        """s'(t) (3,): the given motion_velocity, else the central difference with h = FD_STEP max(1, |t|)."""
        if self._motion is None:
            return np.zeros(3)
        if self._motion_velocity is not None:
            return self._call("motion_velocity", self._motion_velocity, t)
        h = FD_STEP * max(1.0, abs(t))
        return (self._shift(t + h) - self._shift(t - h)) / (2.0 * h)

    def _to_reference(self, x: Array, t: float) -> Array:
        c = self._centre[:, None]
        return c + _rotate(x - self._shift(t)[:, None] - c, -self._omega * t)

    def _from_reference(self, y: Array, t: float) -> Array:
        c = self._centre[:, None]
        x: Array = c + _rotate(y - c, self._omega * t) + self._shift(t)[:, None]
        return x

    def distance(self, x: Any, t: float = 0.0) -> tuple[Array, Array]:
        """(phi, normal) at the points x (3, n) at the time t: phi (n,) the signed distance to the
        surface (> 0 in the free space, < 0 inside the obstacle), normal (3, n) the unit vector
        grad phi (from the obstacle into the free space; where grad phi is undefined, the vector
        the shape's docstring names). Vectorised, finite everywhere."""
        phi, normal = self._distance0(self._to_reference(points(x), float(t)))
        return phi, _rotate(normal, self._omega * float(t))

    def velocity(self, x: Any, t: float) -> Array:
        """The velocity (3, n) of the obstacle's material point at x at the time t (0 if fixed)."""
        r = points(x) - self._shift(float(t))[:, None] - self._centre[:, None]
        v: Array = self._shift_rate(float(t))[:, None] + self._omega * np.vstack([-r[1], r[0], 0.0 * r[2]])  # w e_z x r
        return v

    def carry(self, x: Any, t0: float, t1: float) -> Array:
        """Where (3, n) the obstacle's material points at x at the time t0 are at the time t1 (x itself if
        it is fixed): the obstacle's own displacement there, which a friction slip is measured against."""
        return self._from_reference(self._to_reference(points(x), float(t0)), float(t1))

    def describe(self) -> dict[str, Any]:
        """JSON-able: kind, parameters, motion ("fixed" or what moves it)."""
        motion: Any = {} if self.moves else "fixed"
        if self._motion is not None:
            given = self._motion_velocity
            motion.update({"translation": getattr(self._motion, "__qualname__", repr(self._motion)),
                           "s(0)": self._shift(0.0).tolist(),
                           "velocity": getattr(given, "__qualname__", "given") if given is not None else
                           f"central difference, h = {FD_STEP:g} max(1, |t|)"})
        if self._omega != 0.0:
            motion["rotation"] = {"centre": self._centre.tolist(), "omega": self._omega}
        return {"kind": self.kind, "parameters": self._parameters(), "motion": motion}

    def outline(self, t: float, box: Sequence[Any]) -> list[Array]:
        """Polylines (k, 3) of the surface's section z = 0 at the time t, clipped to the box ``(lo, hi)``
        (x and y), for pictures; [] for a box with a z extent (3-D) or a shape that is not planar."""
        lo, hi = (vector(b, "outline: the box's corner") for b in box)
        if not np.all(hi >= lo):
            raise ObstacleError(f"outline: the box must have hi >= lo, got {box!r}")
        if hi[2] > lo[2] or not self.planar:
            return []
        # the declared outline must cross the box's pre-image: a square about its moved-back centre
        mid = self._to_reference(((lo + hi) / 2)[:, None], float(t))[:, 0]
        pad = 0.5 * float(np.linalg.norm(hi[:2] - lo[:2])) * np.array([1.0, 1.0, 0.0]) * (1 + 1e-9)
        out = []
        for line in self._reference_outline(mid - pad, mid + pad):
            out.extend(clip_polyline(self._from_reference(np.asarray(line, dtype=float).T, float(t)).T, lo, hi))
        return out


def clip_polyline(p: Array, lo: Array, hi: Array) -> list[Array]:
    """The pieces of the polyline p (k, 3) inside the rectangle [lo, hi] (x and y): Liang-Barsky on
    every segment, a piece continued while its segments join."""
    a, b = p[:-1], p[1:]
    d = b - a
    t0, t1 = np.zeros(len(a)), np.ones(len(a))
    for k in range(2):                        # a + t d >= lo and a + t d <= hi, as pk t <= qk
        for pk, qk in ((-d[:, k], a[:, k] - lo[k]), (d[:, k], hi[k] - a[:, k])):
            r = np.divide(qk, pk, out=np.zeros_like(qk), where=pk != 0)
            t0 = np.where(pk < 0, np.maximum(t0, r), t0)
            t1 = np.where(pk > 0, np.minimum(t1, r), np.where((pk == 0) & (qk < 0), -1.0, t1))
    start = np.where((t0 == 0)[:, None], a, a + t0[:, None] * d)        # the ends exactly, so pieces join
    end = np.where((t1 == 1)[:, None], b, a + t1[:, None] * d)
    pieces: list[list[Array]] = []
    for i in np.flatnonzero(t0 <= t1):
        if pieces and i > 0 and t0[i] == 0 and t1[i - 1] == 1 and t0[i - 1] <= t1[i - 1]:
            pieces[-1].append(end[i])
        else:
            pieces.append([start[i], end[i]])
    return [np.array(c) for c in pieces]
