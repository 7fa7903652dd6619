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

A treatment is one module with a factory ``make(context, options)`` and one :func:`register`
line below: ``penalty`` (:mod:`.penalty`) and ``nitsche`` (:mod:`.nitsche`). Their options
(:data:`OPTIONS`; None: the treatment's documented default) come from ``contact_options``.
"""
import math

from sdm_dolfinx.contact import nitsche, penalty
from sdm_dolfinx.contact.context import StepContext

#: the treatment the Integrator handles itself (the variational inequality)
EXACT = "exact"

#: every option of every treatment, and the treatment it belongs to
OPTIONS = {"penalty": "penalty", "nitsche_theta": "nitsche", "nitsche_gamma0": "nitsche"}

_FACTORIES = {}


def register(name, factory):
    """Make ``factory(context, options) -> treatment`` the contact treatment ``name`` (``context``:
    a :class:`~.context.StepContext`)."""
    if name == EXACT or name in _FACTORIES:
        raise ValueError(f"a contact treatment {name!r} exists already")
    _FACTORIES[name] = factory
    return factory


def names():
    """The contact treatments a run may name: ``"exact"`` first, then the registered ones."""
    return (EXACT, *_FACTORIES)


def check(name, options=None):
    """The one-line messages refusing ``name`` with ``options`` (empty when fine): an unknown
    treatment, an unknown option, an option of another treatment, a value out of range."""
    options = {k: v for k, v in dict(options or {}).items() if v is not None}
    if name not in names():
        return [f"unknown contact treatment {name!r}; choose one of {', '.join(names())}"]
    bad = []
    for key, value in options.items():
        owner = OPTIONS.get(key)
        if owner is None:
            bad.append(f"unknown contact option {key!r}; choose among {', '.join(OPTIONS)}")
        elif owner != name:
            bad.append(f"option {key!r} belongs to contact={owner!r}, not contact={name!r}")
        elif key == "nitsche_theta":
            if not _number(value) or value not in nitsche.THETAS:
                bad.append(f"nitsche_theta must be one of {', '.join(map(str, nitsche.THETAS))} (got {value!r})")
        elif not _number(value) or not 0.0 < value < math.inf:
            bad.append(f"{key} must be a finite number > 0 (got {value!r})")
    return bad


def _number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def make(name, context, options=None):
    """The treatment ``name`` for the step of ``context`` (a :class:`~.context.StepContext`: K,
    discretisation, dt, block, factor_matrix); ``options`` a dict among :data:`OPTIONS` (None
    values: the defaults).

    Raises:
        ValueError: what :func:`check` refuses (``"exact"`` included: the Integrator's own).
        TypeError: ``context`` is not a StepContext (a treatment is never given the Integrator).
        DiscretisationError: the treatment does not apply to this problem (one line, why).
    """
    if name == EXACT:
        raise ValueError("contact='exact' is the Integrator's own variational inequality, not a treatment to make")
    bad = check(name, options)
    if bad:
        raise ValueError("; ".join(bad))
    if not isinstance(context, StepContext):
        raise TypeError(f"contact.make takes a StepContext, got {type(context).__name__}")
    options = {k: v for k, v in dict(options or {}).items() if v is not None}
    return _FACTORIES[name](context, options)


register("penalty", penalty.make)
register("nitsche", nitsche.make)
