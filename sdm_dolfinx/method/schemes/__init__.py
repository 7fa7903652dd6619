"""Time schemes: one file each, behind one registry.

Every scheme turns a step of the semi-discrete problem (5) (or the (U, V) block form (4))
into one LCP with a constant matrix (see :mod:`sdm_dolfinx.method.integrator`):

    (alpha^2 M + A) X = L + M (alpha Vbar^n + alpha^2 U^n) + lam,    alpha = factor / dt,

for its constrained iterate X, and then updates (U, V) from X. A scheme is a
:class:`Scheme`: its ``factor``, the name of X, and the update. Adding one is one new file
here calling :func:`register`, plus its tests.
"""
from sdm_dolfinx.method.schemes.base import Scheme

_REGISTRY = {}


def register(scheme):
    """Add a :class:`Scheme` instance to the registry."""
    if not isinstance(scheme, Scheme):
        raise TypeError(f"register() takes a Scheme, got {type(scheme).__name__}")
    _REGISTRY[scheme.name] = scheme
    return scheme


def get(name):
    """The registered scheme ``name``; ValueError listing the choices otherwise."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown scheme {name!r}; choose one of {', '.join(_REGISTRY)}") from None


def names():
    return tuple(_REGISTRY)


from sdm_dolfinx.method.schemes import backward_euler, midpoint  # noqa: E402

register(midpoint.SCHEME)
register(backward_euler.SCHEME)
