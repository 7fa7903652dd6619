"""Rigid obstacles as signed distances phi(x, t) (> 0 in the free space) with their normals grad phi and
a rigid motion (docs/obstacles.md); geometry only. One registry of shapes (:func:`register`, :func:`names`,
:func:`get`, :func:`make`): a new shape is one file (an :class:`Obstacle`) and one ``register`` line here.
"""
from __future__ import annotations

import inspect
from typing import Any

from sdm_dolfinx.obstacles.base import Obstacle, ObstacleError
from sdm_dolfinx.obstacles.ball import Ball
from sdm_dolfinx.obstacles.cylinder import Cylinder
from sdm_dolfinx.obstacles.halfspace import HalfSpace
from sdm_dolfinx.obstacles.surface_mesh import SurfaceMesh
from sdm_dolfinx.obstacles.wedge import Wedge

__all__ = ["Obstacle", "ObstacleError", "Ball", "Cylinder", "HalfSpace", "SurfaceMesh", "Wedge",
           "register", "names", "get", "make"]

_REGISTRY: dict[str, type[Obstacle]] = {}
#: the motion keywords every shape takes (Obstacle.__init__)
MOTION_KEYS = ("motion", "motion_velocity", "rotation")


def register(kind: str, cls: type[Obstacle]) -> type[Obstacle]:
    """Add the shape ``cls`` under the name ``kind`` (its ``kind`` attribute must agree)."""
    if not (isinstance(cls, type) and issubclass(cls, Obstacle)):
        raise ObstacleError(f"register({kind!r}, ...) takes a subclass of Obstacle, got {cls!r}")
    if cls.kind != kind:
        raise ObstacleError(f"register({kind!r}, {cls.__name__}): the class's kind is {cls.kind!r}")
    old = _REGISTRY.get(kind)
    if old is not None and old is not cls:
        raise ObstacleError(f"an obstacle kind {kind!r} is already registered ({old.__name__}); choose another name")
    _REGISTRY[kind] = cls
    return cls


def names() -> list[str]:
    """The registered kinds, sorted."""
    return sorted(_REGISTRY)


def get(kind: str) -> type[Obstacle]:
    """The class registered as ``kind``."""
    try:
        return _REGISTRY[kind]
    except (KeyError, TypeError):
        raise ObstacleError(f"unknown obstacle kind {kind!r}; known: {', '.join(names())}") from None


def make(kind: str, **params: Any) -> Obstacle:
    """The obstacle ``kind`` built from ``params``; a missing or unknown parameter refused in one line."""
    cls = get(kind)
    own = list(inspect.signature(cls.__init__).parameters.values())[1:]
    takes = [p.name for p in own if p.kind is not p.VAR_KEYWORD] + list(MOTION_KEYS)
    unknown = sorted(set(params) - set(takes))
    missing = [p.name for p in own if p.default is p.empty and p.kind is not p.VAR_KEYWORD and p.name not in params]
    if unknown or missing:
        what = f"unknown parameter(s) {', '.join(map(repr, unknown))}" if unknown else \
            f"missing parameter(s) {', '.join(map(repr, missing))}"
        raise ObstacleError(f"obstacle {kind!r}: {what}; takes {', '.join(takes)}")
    return cls(**params)


register("half-space", HalfSpace)
register("ball", Ball)
register("cylinder", Cylinder)
register("wedge", Wedge)
register("surface-mesh", SurfaceMesh)
