"""Materials: the strain energy of a body, linear (the Problem's own ``a(u, w)``) or hyperelastic.

A hyperelastic :class:`~.base.Material` is a strain energy density psi(C) of the right
Cauchy-Green tensor C = F^T F (total Lagrangian, reference configuration), so that it is
objective by construction and the energy-momentum scheme conserves the angular momentum
(:mod:`.algorithmic`). The registry holds one material per file:

- ``linear``: the Problem's own bilinear form (the default; no finite strain);
- ``svk``: Saint Venant-Kirchhoff (:mod:`.svk`);
- ``neo-hookean``: compressible neo-Hookean (:mod:`.neo_hookean`);
- ``problem``: the Problem's own ``strain_energy(C, d)`` (a problem file's psi, :mod:`.problem`).

A new material is one new file calling :func:`register`.
"""
from __future__ import annotations

from sdm_dolfinx.materials.base import LINEAR, Material, MaterialError

_REGISTRY: dict[str, Material] = {}


def register(material: Material) -> Material:
    """Add ``material`` under its name (a later one of the same name replaces it)."""
    _REGISTRY[material.name] = material
    return material


def names() -> tuple[str, ...]:
    """The registered materials' names, ``linear`` first."""
    return (LINEAR, *(n for n in _REGISTRY if n != LINEAR))


def get(name: str) -> Material:
    """The material called ``name``; MaterialError (one line) for an unknown one or ``linear``
    (which has no strain energy of its own: the Problem's ``a(u, w)``)."""
    if name not in _REGISTRY:
        raise MaterialError(f"unknown material {name!r}; choose one of {', '.join(names())}")
    return _REGISTRY[name]


def is_linear(name: str | None) -> bool:
    """Whether ``name`` (None: the default) is the linear model."""
    return name in (None, LINEAR)


from sdm_dolfinx.materials import svk as _svk, neo_hookean as _nh, problem as _problem  # noqa: E402

for _m in (_svk.MATERIAL, _nh.MATERIAL, _problem.MATERIAL):
    register(_m)

__all__ = ["LINEAR", "Material", "MaterialError", "get", "is_linear", "names", "register"]
