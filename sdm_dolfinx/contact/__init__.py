"""Contact treatments: how the constraint u_c >= bound enters a time step (a registry).

``"exact"`` (the default) is no treatment of this package: the Integrator's step is the
variational inequality (the paper's method, solved by the semi-smooth Newton). The others
replace it by a nonlinear force lam(X) of the scheme's constrained iterate X, so that a step is

    K X = b + lam(X)              (K = alpha^2 M + A, constant, Dirichlet rows eliminated)

``contact.make(name, context, options)`` is called by the Integrator once K is built, with a
:class:`~.context.StepContext` (``K``, ``discretisation``, ``dt``, ``block``, ``factor_matrix``:
read-only, all a treatment may rely on; never the Integrator), and returns a treatment with

* ``solver``: a step solver (``solve(b, X) -> {"its", "n_active"}``, ``lam`` the nodal contact
  force at the owned constrained dofs, >= 0 when it pushes, ``active``, ``total_linear_its``,
  ``destroy()``) for that equation;
* ``energy(U)``: the energy stored in the treatment at the state U (collective), which enters
  the balance kinetic + potential + contact energy;
* ``force(X, out)``: ``out`` = lam(X) as a vector of W^h (explicit schemes evaluate it at U^n);
* ``nodal_forces(X)``: the nodal contact forces the solver reports as ``lam`` (owned constrained
  dofs) at the state X, for a scheme that evaluates the force itself;
* ``describe()``: the options and the parameters they gave (for run.json);
* ``destroy()``.

A treatment is one module with a factory ``make(context, options)``, its options declared as
:class:`~sdm_dolfinx.params.Param` (default, bounds, help), and one :func:`register` line below:
``penalty`` (:mod:`.penalty`) and ``nitsche`` (:mod:`.nitsche`). Their values (None: the
declared default, which the treatment applies) come from ``contact_options``; the run options,
the command line's ``--name`` and every check of a value derive from the declarations.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any, Optional, Protocol

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.contact import nitsche, penalty
from sdm_dolfinx.contact.context import StepContext as StepContext
from sdm_dolfinx.params import OptionError, Param, check_given

if TYPE_CHECKING:
    from petsc4py import PETSc

#: the treatment the Integrator handles itself (the variational inequality)
EXACT = "exact"


class Treatment(Protocol):
    """What a factory returns (the module docstring): the step solver of K X = b + lam(X) and
    the contact force lam."""
    solver: Any

    def energy(self, U: PETSc.Vec) -> float: ...
    # (a treatment that takes moving obstacles, the penalty, has energy(U, time): the obstacle at the
    # state's time; the Integrator passes it then)

    def force(self, X: PETSc.Vec, out: PETSc.Vec) -> PETSc.Vec: ...

    def nodal_forces(self, X: PETSc.Vec) -> npt.NDArray[np.float64]: ...

    def describe(self) -> dict[str, Any]: ...

    def destroy(self) -> None: ...


#: ``factory(context, options) -> treatment``
Factory = Callable[[StepContext, dict[str, Any]], Treatment]

#: name -> (factory, declared options)
_FACTORIES: dict[str, tuple[Factory, tuple[Param, ...]]] = {}


def register(name: str, factory: Factory, options: Iterable[Param] = ()) -> Factory:
    """Make ``factory(context, options) -> treatment`` the contact treatment ``name`` (``context``: a
    :class:`~.context.StepContext`), whose options are the :class:`~sdm_dolfinx.params.Param`
    declarations ``options`` (``factory`` receives the ones given, without None values)."""
    if name == EXACT or name in _FACTORIES:
        raise ValueError(f"a contact treatment {name!r} exists already")
    _FACTORIES[name] = (factory, tuple(options))
    return factory


def unregister(name: str) -> None:
    """Remove the contact treatment ``name`` (registered by user code; a test's clean-up)."""
    _FACTORIES.pop(name, None)


def names() -> tuple[str, ...]:
    """The contact treatments a run may name: ``"exact"`` first, then the registered ones."""
    return (EXACT, *_FACTORIES)


def options_of(name: str) -> tuple[Param, ...]:
    """The options the treatment ``name`` declares (``"exact"``: none)."""
    return () if name == EXACT else _FACTORIES[name][1]


def check(name: str, options: Optional[Mapping[str, Any]] = None) -> list[str]:
    """The one-line messages refusing ``name`` with ``options`` (empty when fine): an unknown
    treatment, an option it does not declare, a value its declaration refuses."""
    if name not in names():
        return [f"unknown contact treatment {name!r}; choose one of {', '.join(names())}"]
    return check_given(f"contact {name}", options_of(name), dict(options or {}))


def make(name: str, context: StepContext, options: Optional[Mapping[str, Any]] = None) -> Treatment:
    """The treatment ``name`` for the step of ``context`` (a :class:`~.context.StepContext`: K,
    discretisation, dt, block, factor_matrix); ``options`` a dict of its declared options (None
    values: the defaults).

    Raises:
        OptionError: what :func:`check` refuses (``"exact"`` included: the Integrator's own).
        TypeError: ``context`` is not a StepContext (a treatment is never given the Integrator).
        DiscretisationError: the treatment does not apply to this problem (one line, why).
    """
    if name == EXACT:
        raise ValueError("contact='exact' is the Integrator's own variational inequality, not a treatment to make")
    bad = check(name, options)
    if bad:
        raise OptionError("; ".join(bad))
    if not isinstance(context, StepContext):
        raise TypeError(f"contact.make takes a StepContext, got {type(context).__name__}")
    options = {k: v for k, v in dict(options or {}).items() if v is not None}
    return _FACTORIES[name][0](context, options)


register("penalty", penalty.make, penalty.OPTIONS)
register("nitsche", nitsche.make, nitsche.OPTIONS)
