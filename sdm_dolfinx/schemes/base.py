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
import copy

from sdm_dolfinx.params import values_of


class Scheme:
    """A one-step scheme whose step is one LCP in a constrained iterate X.

    Attributes:
        name: the registry's name (the ``--scheme`` choice).
        factor: alpha = factor / dt in the step matrix alpha^2 M + A (None: the scheme gives
            :meth:`coefficients` itself).
        constrained: the iterate the constraint is imposed on (for ``run.json``).
        load_theta: a time-dependent load of step n -> n+1 is evaluated at t_n + load_theta dt
            (None: the scheme does not say, and refuses time-dependent loads).
        options: the scheme's options (``scheme_options``), each a
            :class:`~sdm_dolfinx.params.Param` (default, bounds, help): the run options, the
            command line's ``--name`` and the checks of a value all derive from it.
        explicit: the step matrix holds no stiffness (c_A = 0): the step is CFL-bounded.
        stateful: the scheme keeps state between steps beyond (U, V) (a checkpoint of U and V
            cannot restart it).
    """
    name = None
    factor = None
    constrained = None
    load_theta = None
    options = ()
    explicit = False
    stateful = False

    # ------------------------------------------------------------------ set-up
    def configure(self, options=None):
        """A copy of this scheme for one run, with ``options`` (a dict; None values: the
        defaults of :attr:`options`). OptionError (a ValueError, one line) on an option this
        scheme does not declare or a value its declaration refuses."""
        values = values_of(f"scheme {self.name}", self.options, dict(options or {}))
        scheme = copy.copy(self)
        scheme.set_parameters(**values)
        return scheme

    def set_parameters(self, **values):
        """Set the values of :attr:`options` (checked by their declarations) on this copy."""
        for k, v in values.items():
            setattr(self, k, v)

    def refuse(self, integ):
        """The one-line reason this scheme cannot run with ``integ``'s discretisation, contact
        treatment, friction or solver, or None (default: None)."""
        return None

    def setup(self, integ):
        """What the step matrix needs, before it is built (default: nothing)."""

    def coefficients(self, dt):
        """(c_M, c_A) of the step matrix K = c_M M + c_A A: (alpha^2, 1), alpha = factor / dt."""
        if self.factor is None:
            raise NotImplementedError(f"scheme {self.name!r} has no factor: it must define coefficients()")
        alpha = self.factor / dt
        return alpha * alpha, 1.0

    def step_matrix(self, integ):
        """The step matrix before the Dirichlet elimination, or None for c_M M + c_A A."""
        return None

    def solver_bounds(self, integ):
        """The bounds array given to the step solver (default: the discretisation's own; a
        scheme that changes them every step returns a copy it keeps)."""
        return integ.discretisation.lb

    def prepare(self, integ):
        """Once K, the step solver and the contact treatment exist (default: nothing)."""

    # ------------------------------------------------------------------ one step
    def load_time(self, t, dt):
        """The time at which the step from ``t`` to ``t + dt`` evaluates a time-dependent load."""
        if self.load_theta is None:
            raise ValueError(f"scheme {self.name!r} does not say when it evaluates a time-dependent load "
                             f"(Scheme.load_theta)")
        return t + self.load_theta * dt

    def start(self, integ, U, V, t):
        """The scheme's state before its first step from (U, V) at time t (stateful schemes)."""
        return None

    def rhs(self, integ, U, V, L, t):
        """The step's right-hand side b (``integ.b``, Dirichlet lifting applied) for the state
        (U^n, V^n) at time t and the step's load vector L."""
        return integ.alpha_rhs(U, V, L)

    def guess(self, integ, U, V, X):
        """The solver's initial guess in X (default: U^n, and V^n for the block variant)."""
        X.array[:integ.nW] = U.array
        if integ.block:
            X.array[integ.nW:] = V.array

    def update(self, integ, X, U, V, t):
        """(U, V) <- (U^{n+1}, V^{n+1}) in place from the solution X of the step's LCP."""
        nW = integ.nW
        x = X.array[:nW]
        Un = U.array.copy()
        U.array[:] = self.displacement(x, Un)
        if integ.block:
            V.array[:] = self.velocity_block(X.array[nW:], V.array)
        else:
            V.array[:] = self.velocity(x, Un, V.array, integ.alpha)

    def destroy(self, integ):
        """Free what :meth:`setup` and :meth:`prepare` made (default: nothing)."""

    def imposed_gap(self, integ, X):
        """min over the owned constrained dofs of (constrained iterate - its bound) (local)."""
        d = integ.discretisation
        return float((X.array[d.cdofs] - d.lb).min(initial=float("inf")))

    def needs_m_formulation(self, integ):
        """The refusal of the (U, V) block variant (``mass="consistent"``), for the schemes
        written in the M formulation only, or None."""
        if integ.block:
            return (f"scheme {self.name!r} is written in the M formulation; mass 'consistent' solves the (U, V) "
                    f"block system instead: use mass 'lumped' (or the midpoint / backward-euler scheme)")
        return None

    # ------------------------------------------------------- alpha-family updates
    def displacement(self, x, Un):
        """U^{n+1} from the constrained iterate x and U^n (arrays)."""
        raise NotImplementedError

    def velocity(self, x, Un, Vn, alpha):
        """Vbar^{n+1} (the M formulation) from x, U^n, Vbar^n."""
        raise NotImplementedError

    def velocity_block(self, y, Vn):
        """V^{n+1} in H^h (the block formulation) from the block's second unknown y and V^n."""
        raise NotImplementedError
