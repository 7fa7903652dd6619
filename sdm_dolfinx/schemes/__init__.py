"""Time schemes: one file each, behind one registry.

Every scheme turns a step of the semi-discrete problem (5) (or the (U, V) block form (4))
into one LCP with a constant matrix K = c_M M + c_A A (see :mod:`sdm_dolfinx.run.integrator`)
for its constrained iterate X, and then updates (U, V) from X; the paper's schemes have

    (alpha^2 M + A) X = L + M (alpha Vbar^n + alpha^2 U^n) + lam,    alpha = factor / dt.

A scheme is a :class:`Scheme` (its hooks: :mod:`~sdm_dolfinx.schemes.base`). Adding one
is one new file here calling :func:`register`, plus its tests. The schemes:

* ``midpoint``, ``backward-euler``: the paper's (constraint on U^{n+1/2}, U^{n+1});
* ``newmark`` (beta = 1/4, gamma = 1/2), ``hht`` (HHT-alpha): implicit, constraint on U^{n+1},
  the acceleration kept between steps (stateful);
* ``central-difference``, ``paoli-schatzman`` (restitution e), ``taylor-flanagan``: explicit,
  one solve with M per step, CFL-bounded (:mod:`~sdm_dolfinx.schemes.explicit`).
"""
from sdm_dolfinx.schemes.base import Scheme as Scheme

_REGISTRY: dict[str, Scheme] = {}


def register(scheme: Scheme) -> Scheme:
    """Add a :class:`Scheme` instance to the registry."""
    if not isinstance(scheme, Scheme):
        raise TypeError(f"register() takes a Scheme, got {type(scheme).__name__}")
    if not isinstance(scheme.name, str):        # the registry's key: --scheme NAME, run.json
        raise TypeError(f"register() takes a Scheme with a name (a str), got name {scheme.name!r}")
    _REGISTRY[scheme.name] = scheme
    return scheme


def get(name: str) -> Scheme:
    """The registered scheme ``name``; ValueError listing the choices otherwise."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown scheme {name!r}; choose one of {', '.join(_REGISTRY)}") from None


def names() -> tuple[str, ...]:
    return tuple(_REGISTRY)


from sdm_dolfinx.schemes import (backward_euler, central_difference, hht, midpoint, newmark,  # noqa: E402
                                        paoli_schatzman, taylor_flanagan)

register(midpoint.SCHEME)
register(backward_euler.SCHEME)
register(newmark.SCHEME)
register(hht.SCHEME)
register(central_difference.SCHEME)
register(paoli_schatzman.SCHEME)
register(taylor_flanagan.SCHEME)
