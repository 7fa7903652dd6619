"""What a time scheme is (see :mod:`sdm_dolfinx.schemes`).

A scheme turns a step into one LCP  K X = b + lam  in a constrained iterate X, with a constant
step matrix K, and updates (U, V) from X. The :class:`~sdm_dolfinx.run.integrator.Integrator`
calls its hooks in this order (``integ`` is the Integrator, which offers the products with M
and A, the load and the Dirichlet lifting):

1. :meth:`configure` (the scheme's options, declared in :attr:`Scheme.options`:
   ``scheme_options``), then :meth:`refuse` (one line: a combination the scheme cannot run)
   and :meth:`setup` (what K needs, e.g. the mass solver of an explicit scheme);
2. :meth:`step_matrix` (None: K = c_M M + c_A A with :meth:`coefficients`), the step solver;
3. :meth:`prepare` (once K, the solver and the contact treatment exist: the CFL check);
4. every step: :meth:`start` (the first step of a stateful scheme), :meth:`rhs`, the solve,
   :meth:`update`.

The defaults are the one-LCP schemes of the paper, K = alpha^2 M + A with alpha = factor / dt
and b = L + M (alpha Vbar^n + alpha^2 U^n) (midpoint, backward Euler), which only declare
``factor``, ``displacement``, ``velocity`` and ``velocity_block``.
"""
from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Optional, TypeVar

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.params import Param, values_of

if TYPE_CHECKING:
    from petsc4py import PETSc

#: the run's :class:`~sdm_dolfinx.run.integrator.Integrator`, which a layer below cannot import
Integrator = Any
#: an array of the owned dofs
Array = npt.NDArray[np.float64]
_S = TypeVar("_S", bound="Scheme")


class Scheme:
    """A one-step scheme whose step is one LCP in a constrained iterate X.

    Attributes:
        name: the registry's name (the ``--scheme`` choice).
        factor: alpha = factor / dt in the step matrix alpha^2 M + A (None: the scheme gives
            :meth:`coefficients` itself).
        constrained: the iterate the constraint is imposed on (for ``run.json``).
        load_theta: a time-dependent load of step n -> n+1 is evaluated at t_n + load_theta dt
            (None: the scheme does not say, and refuses time-dependent loads).
        bound_weight: a moving bound (``Problem.moving_bound``) is imposed on X at the step's
            bound (1 - bound_weight) g(t_n) + bound_weight g(t_{n+1}) (:meth:`step_bound`; None: the
            scheme does not say, and refuses a moving bound).
        options: the scheme's options (``scheme_options``), each a
            :class:`~sdm_dolfinx.params.Param` (default, bounds, help): the run options, the
            command line's ``--name`` and the checks of a value all derive from it.
        explicit: the step matrix holds no stiffness (c_A = 0): the step is CFL-bounded.
        stateful: the scheme keeps state between steps beyond (U, V) (a checkpoint of U and V
            cannot restart it).
        moving_dirichlet: the scheme takes the Problem's Dirichlet parts (data that may move,
            :meth:`dirichlet_iterate`); the others refuse a Problem declaring any, in one line.
        finite_strain: the internal force of a hyperelastic material's step
            (:data:`sdm_dolfinx.materials.algorithmic.KINDS`: ``"energy-momentum"``, ``"endpoint"``), or
            None: the scheme refuses a hyperelastic material in one line.
    """
    name: Optional[str] = None
    factor: Optional[float] = None
    constrained: Optional[str] = None
    load_theta: Optional[float] = None
    bound_weight: Optional[float] = None
    options: tuple[Param, ...] = ()
    explicit: bool = False
    stateful: bool = False
    moving_dirichlet: bool = False
    finite_strain: Optional[str] = None

    # ------------------------------------------------------------------ set-up
    def configure(self: _S, options: Optional[Mapping[str, Any]] = None) -> _S:
        """A copy of this scheme for one run, with ``options`` (a dict; None values: the
        defaults of :attr:`options`). OptionError (a ValueError, one line) on an option this
        scheme does not declare or a value its declaration refuses."""
        values = values_of(f"scheme {self.name}", self.options, dict(options or {}))
        scheme = copy.copy(self)
        scheme.set_parameters(**values)
        return scheme

    def set_parameters(self, **values: Any) -> None:
        """Set the values of :attr:`options` (checked by their declarations) on this copy."""
        for k, v in values.items():
            setattr(self, k, v)

    def refuse(self, integ: Integrator) -> Optional[str]:
        """The one-line reason this scheme cannot run with ``integ``'s discretisation, contact
        treatment, friction or solver, or None (default: None)."""
        return None

    def setup(self, integ: Integrator) -> None:
        """What the step matrix needs, before it is built (default: nothing)."""

    def coefficients(self, dt: float) -> tuple[float, float]:
        """(c_M, c_A) of the step matrix K = c_M M + c_A A: (alpha^2, 1), alpha = factor / dt."""
        if self.factor is None:
            raise NotImplementedError(f"scheme {self.name!r} has no factor: it must define coefficients()")
        alpha = self.factor / dt
        return alpha * alpha, 1.0

    def step_matrix(self, integ: Integrator) -> Optional[PETSc.Mat]:
        """The step matrix before the Dirichlet elimination, or None for c_M M + c_A A."""
        return None

    def solver_bounds(self, integ: Integrator) -> Array:
        """The bounds array given to the step solver (default: the discretisation's own; a
        scheme that changes them every step returns a copy it keeps)."""
        lb: Array = integ.discretisation.lb
        return lb

    def prepare(self, integ: Integrator) -> None:
        """Once K, the step solver and the contact treatment exist (default: nothing)."""

    # ------------------------------------------------------------------ one step
    def load_time(self, t: float, dt: float) -> float:
        """The time at which the step from ``t`` to ``t + dt`` evaluates a time-dependent load."""
        if self.load_theta is None:
            raise ValueError(f"scheme {self.name!r} does not say when it evaluates a time-dependent load "
                             f"(Scheme.load_theta)")
        return t + self.load_theta * dt

    def step_bound(self, g0: Array, g1: Array) -> Array:
        """The bound the step from t_n to t_{n+1} imposes on X, from a moving bound's values g0 at
        t_n and g1 at t_{n+1}: (1 - w) g0 + w g1, w = :attr:`bound_weight` (w = 1: g1 exactly)."""
        w = self.bound_weight
        if w is None:
            raise ValueError(f"scheme {self.name!r} does not say at which time it imposes a moving bound "
                             f"(Scheme.bound_weight)")
        return g1.copy() if w == 1.0 else (1.0 - w) * g0 + w * g1

    def start(self, integ: Integrator, U: PETSc.Vec, V: PETSc.Vec, t: float) -> Any:
        """The scheme's state before its first step from (U, V) at time t (stateful schemes)."""
        return None

    def rhs(self, integ: Integrator, U: PETSc.Vec, V: PETSc.Vec, L: PETSc.Vec, t: float) -> PETSc.Vec:
        """The step's right-hand side b (``integ.b``, Dirichlet lifting applied) for the state
        (U^n, V^n) at time t and the step's load vector L."""
        return integ.alpha_rhs(U, V, L)

    def dirichlet_iterate(self, u_next: Array, Un: Array) -> Array:
        """The constrained iterate X at a Dirichlet part's dofs for which :meth:`update` gives
        U^{n+1} = ``u_next`` = u_D(t_{n+1}) from ``Un`` = U^n there (schemes with
        :attr:`moving_dirichlet`)."""
        raise NotImplementedError(f"scheme {self.name!r} does not take Dirichlet parts")

    def guess(self, integ: Integrator, U: PETSc.Vec, V: PETSc.Vec, X: PETSc.Vec) -> None:
        """The solver's initial guess in X (default: U^n, and V^n for the block variant)."""
        X.array[:integ.nW] = U.array
        if integ.block:
            X.array[integ.nW:] = V.array

    def update(self, integ: Integrator, X: PETSc.Vec, U: PETSc.Vec, V: PETSc.Vec, t: float) -> None:
        """(U, V) <- (U^{n+1}, V^{n+1}) in place from the solution X of the step's LCP."""
        nW = integ.nW
        x = X.array[:nW]
        Un = U.array.copy()
        U.array[:] = self.displacement(x, Un)
        if integ.block:
            V.array[:] = self.velocity_block(X.array[nW:], V.array)
        else:
            V.array[:] = self.velocity(x, Un, V.array, integ.alpha)

    def destroy(self, integ: Integrator) -> None:
        """Free what :meth:`setup` and :meth:`prepare` made (default: nothing)."""

    def imposed_gap(self, integ: Integrator, X: PETSc.Vec) -> float:
        """min over the owned constrained dofs of (constrained iterate - its bound) (local)."""
        d = integ.discretisation
        return float((X.array[d.cdofs] - d.lb).min(initial=float("inf")))

    def needs_m_formulation(self, integ: Integrator) -> Optional[str]:
        """The refusal of the (U, V) block variant (``mass="consistent"``), for the schemes
        written in the M formulation only, or None."""
        if integ.block:
            return (f"scheme {self.name!r} is written in the M formulation; mass 'consistent' solves the (U, V) "
                    f"block system instead: use mass 'lumped' (or the midpoint / backward-euler scheme)")
        return None

    # ------------------------------------------------------- alpha-family updates
    def displacement(self, x: Array, Un: Array) -> Array:
        """U^{n+1} from the constrained iterate x and U^n (arrays)."""
        raise NotImplementedError

    def velocity(self, x: Array, Un: Array, Vn: Array, alpha: float) -> Array:
        """Vbar^{n+1} (the M formulation) from x, U^n, Vbar^n."""
        raise NotImplementedError

    def velocity_block(self, y: Array, Vn: Array) -> Array:
        """V^{n+1} in H^h (the block formulation) from the block's second unknown y and V^n."""
        raise NotImplementedError
