"""The step solvers by name: ``make_vi_solver("ssn", K, cdofs, lb, ...)``.

A step solver is a class with ``solve(b, x) -> {"its", "n_active"}`` (raising
:class:`~sdm_dolfinx.solvers.base.VIError`), ``lam``, ``total_linear_its``, ``prefix`` and
``destroy()``. A new one is one new module plus one :func:`register` line at the end of
this file (or a call from the user's code before the solver is asked for).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, Optional, Protocol, Union, overload

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.solvers.semismooth import SemismoothNewton
from sdm_dolfinx.solvers.snes_vi import SnesVI

if TYPE_CHECKING:
    from petsc4py import PETSc


class StepSolver(Protocol):
    """What a factory returns: ``solve(b, x)`` writes the step's solution into ``x`` and returns
    at least ``{"its", "n_active"}`` (VIError when it fails)."""

    @property
    def lam(self) -> npt.NDArray[np.float64]:
        """The nodal contact forces at the owned constrained dofs (>= 0 when they push)."""

    @property
    def total_linear_its(self) -> int:
        """The linear iterations of every solve so far."""

    @property
    def prefix(self) -> str:
        """The instance's PETSc options prefix."""

    def solve(self, b: PETSc.Vec, x: PETSc.Vec) -> dict[str, Any]: ...

    def destroy(self) -> None: ...


class Factory(Protocol):
    """``factory(K, cdofs, lb, *, symmetric_positive, linear, options, factor_matrix, prefix)``
    (the arguments of :func:`make_vi_solver`)."""

    def __call__(self, K: PETSc.Mat, cdofs: npt.ArrayLike, lb: npt.ArrayLike, /, *, symmetric_positive: bool,
                 linear: str, options: Optional[Mapping[str, Any]], factor_matrix: Optional[PETSc.Mat],
                 prefix: Optional[str]) -> StepSolver: ...


_FACTORIES: dict[str, Factory] = {}


class _Names(Sequence[str]):
    """The registered names in registration order: a read-only tuple that follows
    :func:`register` (for argparse ``choices=`` and ``", ".join(...)``)."""

    @overload
    def __getitem__(self, i: int) -> str: ...

    @overload
    def __getitem__(self, i: slice) -> tuple[str, ...]: ...

    def __getitem__(self, i: Union[int, slice]) -> Union[str, tuple[str, ...]]:
        return tuple(_FACTORIES)[i]

    def __len__(self) -> int:
        return len(_FACTORIES)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Sequence) and tuple(self) == tuple(other)

    def __hash__(self) -> int:
        return hash(tuple(self))

    def __repr__(self) -> str:
        return repr(tuple(self))


#: the names :func:`make_vi_solver` accepts
VI_SOLVERS = _Names()


def register(name: str, factory: Factory) -> Factory:
    """Make ``factory(K, cdofs, lb, *, symmetric_positive, linear, options, factor_matrix,
    prefix)`` the step solver ``name``; returns ``factory``."""
    if name in _FACTORIES:
        raise ValueError(f"a VI solver {name!r} is registered already")
    _FACTORIES[name] = factory
    return factory


def make_vi_solver(name: str, K: PETSc.Mat, cdofs: npt.ArrayLike, lb: npt.ArrayLike, symmetric_positive: bool = True,
                   linear: str = "auto", options: Optional[Mapping[str, Any]] = None,
                   factor_matrix: Optional[PETSc.Mat] = None, prefix: Optional[str] = None) -> StepSolver:
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


def _semismooth_newton(K: PETSc.Mat, cdofs: npt.ArrayLike, lb: npt.ArrayLike, *, symmetric_positive: bool,
                       linear: str, options: Optional[Mapping[str, Any]], factor_matrix: Optional[PETSc.Mat],
                       prefix: Optional[str]) -> SemismoothNewton:
    return SemismoothNewton(K, cdofs, lb, symmetric_positive, linear, prefix=prefix, options=options,
                            factor_matrix=factor_matrix)


def _snes_vi(snes_type: str) -> Factory:
    """The factory of :class:`SnesVI` with SNES type ``snes_type`` (no linear strategy)."""
    def factory(K: PETSc.Mat, cdofs: npt.ArrayLike, lb: npt.ArrayLike, *, symmetric_positive: bool, linear: str,
                options: Optional[Mapping[str, Any]], factor_matrix: Optional[PETSc.Mat],
                prefix: Optional[str]) -> SnesVI:
        return SnesVI(K, cdofs, lb, symmetric_positive, snes_type=snes_type, prefix=prefix, options=options)
    return factory


register("ssn", _semismooth_newton)
register("vinewtonrsls", _snes_vi("vinewtonrsls"))
register("vinewtonssls", _snes_vi("vinewtonssls"))
