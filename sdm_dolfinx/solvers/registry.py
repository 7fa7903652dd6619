"""The step solvers by name: ``make_vi_solver("ssn", K, cdofs, lb, ...)``.

A step solver is a class with ``solve(b, x) -> {"its", "n_active"}`` (raising
:class:`~sdm_dolfinx.solvers.base.VIError`), ``lam``, ``total_linear_its``, ``prefix`` and
``destroy()``. A new one is one new module plus one :func:`register` line at the end of
this file (or a call from the user's code before the solver is asked for).
"""
from collections.abc import Sequence

from sdm_dolfinx.solvers.semismooth import SemismoothNewton
from sdm_dolfinx.solvers.snes_vi import SnesVI

_FACTORIES = {}


class _Names(Sequence):
    """The registered names in registration order: a read-only tuple that follows
    :func:`register` (for argparse ``choices=`` and ``", ".join(...)``)."""

    def __getitem__(self, i):
        return tuple(_FACTORIES)[i]

    def __len__(self):
        return len(_FACTORIES)

    def __eq__(self, other):
        return isinstance(other, Sequence) and tuple(self) == tuple(other)

    def __hash__(self):
        return hash(tuple(self))

    def __repr__(self):
        return repr(tuple(self))


#: the names :func:`make_vi_solver` accepts
VI_SOLVERS = _Names()


def register(name, factory):
    """Make ``factory(K, cdofs, lb, *, symmetric_positive, linear, options, factor_matrix,
    prefix)`` the step solver ``name``; returns ``factory``."""
    if name in _FACTORIES:
        raise ValueError(f"a VI solver {name!r} is registered already")
    _FACTORIES[name] = factory
    return factory


def make_vi_solver(name, K, cdofs, lb, symmetric_positive=True, linear="auto", options=None, factor_matrix=None,
                   prefix=None):
    """Build the step solver ``name`` (one of :data:`VI_SOLVERS`).

    ``factor_matrix``: a sparser augmented matrix to factorise instead of K (semi-smooth
    Newton with ``schur`` or ``cg-factor``; see :func:`~sdm_dolfinx.solvers.augmented.augmented_matrix`).
    ``prefix``: the instance's PETSc options prefix (None: a new ``sdm_<k>_``; read it back
    as ``solver.prefix``); ``options``: PETSc options of this instance only.
    """
    if name not in _FACTORIES:
        raise ValueError(f"unknown VI solver {name!r}; choose one of {', '.join(VI_SOLVERS)}")
    return _FACTORIES[name](K, cdofs, lb, symmetric_positive=symmetric_positive, linear=linear, options=options,
                            factor_matrix=factor_matrix, prefix=prefix)


def _semismooth_newton(K, cdofs, lb, *, symmetric_positive, linear, options, factor_matrix, prefix):
    return SemismoothNewton(K, cdofs, lb, symmetric_positive, linear, prefix=prefix, options=options,
                            factor_matrix=factor_matrix)


def _snes_vi(snes_type):
    """The factory of :class:`SnesVI` with SNES type ``snes_type`` (no linear strategy)."""
    def factory(K, cdofs, lb, *, symmetric_positive, linear, options, factor_matrix, prefix):
        return SnesVI(K, cdofs, lb, symmetric_positive, snes_type=snes_type, prefix=prefix, options=options)
    return factory


register("ssn", _semismooth_newton)
register("vinewtonrsls", _snes_vi("vinewtonrsls"))
register("vinewtonssls", _snes_vi("vinewtonssls"))
