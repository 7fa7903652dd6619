"""What a user's ``simulate(..., observe=f)`` callback sees: ``f(state)``, a read-only :class:`State`.

The callback runs on every rank after each row of the time series (row 0, the initial state,
too) and reads the state; it cannot change it (the arrays are read-only views) and is never
given the Integrator (its solver, scheme and treatment are not for callbacks to touch). The
older form ``f(n, t, U, V, integ)`` still works for this release, with a FutureWarning.
"""
from __future__ import annotations

import inspect
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Optional, Union

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.method import gaps

if TYPE_CHECKING:
    from petsc4py import PETSc

    from sdm_dolfinx.method.discretisation import Discretisation
    from sdm_dolfinx.run.integrator import Integrator

#: the FutureWarning of the older callback form (shown once per process by the default filters)
LEGACY_WARNING = ("observe=f(n, t, U, V, integ) is deprecated and will be removed in the next release: "
                  "write f(state) (sdm_dolfinx.run.State: state.n, state.t, state.U, state.V, state.lam, "
                  "state.discretisation; docs/api.md)")
#: the warnings registry of LEGACY_WARNING: once per process
_warned: dict[Union[str, tuple[str, type[Warning], int]], int] = {}


class ObserveError(SdmError, TypeError):
    """``observe`` is not a callable taking one argument (a :class:`State`)."""


@dataclass(frozen=True)
class State:
    """The state after row ``n`` of the time series, for ``observe`` callbacks (read-only).

    The arrays are read-only views of the run's own vectors, valid during the call: copy what
    you keep (``state.U.copy()``). Methods marked collective must be called on every rank.

    Attributes:
        n: the row (step) number; 0 is the initial state.
        t: its time, n dt.
        U: U^n at the owned dofs of W^h (the displacement's coefficients).
        V: the velocity unknown at the owned dofs: Vbar in W^h, or V in H^h for mass
            ``"consistent"`` (the (U, V) block system; ``discretisation.mass``).
        lam: the nodal contact forces of the last step at the owned constrained dofs (>= 0
            pushes; 0 in row 0 and in a restart's first row).
        discretisation: the run's :class:`~sdm_dolfinx.method.discretisation.Discretisation`
            (spaces, mesh, constrained dofs ``cdofs``, bounds ``lb``, ``comm``); read it only:
            before every step the data assembled once are checked unchanged.
    """

    n: int
    t: float
    U: npt.NDArray[np.float64]
    V: npt.NDArray[np.float64]
    lam: npt.NDArray[np.float64]
    discretisation: Discretisation

    def vertex_gap(self) -> float:
        """min over the constrained vertices of U_c - bound, over every rank (collective)."""
        return gaps.vertex_gap(self.discretisation, self.U, self.t)

    def boundary_gap(self) -> float:
        """min over every dof of W^h on the constrained boundary of U_c - bound, over every rank
        (collective; +inf without such dofs)."""
        return gaps.boundary_gap(self.discretisation, self.U, self.t)


def _read_only(a: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """A copy of ``a`` seen through a view that cannot be made writeable (its base is read-only)."""
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a.view()


class Observer:
    """``simulate``'s ``observe`` callback, called by the loop with the run's vectors: ``f(State)``,
    or the older ``f(n, t, U, V, integ)`` (with a FutureWarning on rank 0 when made).

    Raises:
        ObserveError: ``f`` is not callable, or takes neither one nor five positional arguments.
    """

    def __init__(self, f: Callable[..., object], comm: MPI.Comm) -> None:
        if not callable(f):
            raise ObserveError(f"observe must be a callable f(state), not a {type(f).__name__}")
        one, five = _takes(f, 1), _takes(f, 5)
        self.f, self.legacy = f, one is False and five is True
        if one is False and not self.legacy:
            raise ObserveError(f"observe must take one argument, f(state); {_name(f)} takes {_signature(f)}")
        if self.legacy and comm.rank == 0:
            warnings.warn_explicit(LEGACY_WARNING, FutureWarning, "sdm_dolfinx", 0, registry=_warned)

    def __call__(self, n: int, t: float, U: PETSc.Vec, V: PETSc.Vec, lam: npt.ArrayLike, integ: Integrator) -> None:
        """Call the callback after row ``n`` (U, V: the PETSc vectors; lam: the last step's
        contact forces; integ: given to the older form only)."""
        if self.legacy:
            self.f(n, t, U, V, integ)
            return
        self.f(State(n, t, U.array_r, V.array_r, _read_only(lam), integ.discretisation))


def _takes(f: Callable[..., object], k: int) -> Optional[bool]:
    """Whether ``f`` accepts ``k`` positional arguments (None: its signature is unknown)."""
    try:
        sig = inspect.signature(f)
    except (TypeError, ValueError):
        return None
    try:
        sig.bind(*range(k))
    except TypeError:
        return False
    return True


def _name(f: object) -> str:
    return getattr(f, "__qualname__", None) or type(f).__name__


def _signature(f: Callable[..., object]) -> str:
    return str(inspect.signature(f))
