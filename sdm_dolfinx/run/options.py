"""The run options, declared once: every surface derives from this table.

:data:`TABLE` declares the options every run has (:class:`~sdm_dolfinx.params.RunOption`: name,
type, default, valid values, help, command-line group, whether a restart may change it, whether
it is part of the run's identity). The options of one method are declared by their owner: each
time scheme (:attr:`Scheme.options <sdm_dolfinx.schemes.base.Scheme.options>`), each contact
treatment (:func:`sdm_dolfinx.contact.register`) and each friction law
(:data:`sdm_dolfinx.contact.friction.LAW_OPTIONS`); :func:`declarations` adds them, read from the
registries when asked, so that a scheme or treatment registered by user code is accepted by
:func:`~sdm_dolfinx.run.simulate`, :func:`~sdm_dolfinx.run.plan` and the command line with its
options. From these declarations come ``simulate``'s keywords (a test compares them), the
command line's options (:mod:`sdm_dolfinx.cli.params`), the TOML keys, ``run.json``'s
``run_options`` (flat: one key per option) and what a restart may change.

In Python a method's options are grouped by owner, as dolfinx's ``petsc_options``:
``scheme_options={"hht_alpha": -0.1}``, ``contact_options={"penalty": 1e5}``,
``friction_options={"mu": 0.3}``; :func:`collect` turns the keywords into the flat options
(``run.json``'s names), :func:`grouped` the flat options into keywords.
"""
from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Mapping
from typing import Any, Optional

from sdm_dolfinx import contact, materials, schemes
from sdm_dolfinx.contact import friction as _friction
from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.method import quadrature
from sdm_dolfinx.method.discretisation import CONSTRAIN
from sdm_dolfinx.method.pairs import MASS_TREATMENTS, PAIRS, Pair, get_pair
from sdm_dolfinx.params import Param, RunOption
from sdm_dolfinx.run import solver_rules
from sdm_dolfinx.run.result import num_steps
from sdm_dolfinx.solvers import LINEAR_STRATEGIES, VI_SOLVERS
from sdm_dolfinx.solvers.active_set import missing_package


class RunInputError(SdmError, ValueError):
    """A run's inputs are refused (one line; nothing was written)."""


#: the command line's groups of run options, in the order of ``--help``
RUN, FRICTION, METHOD, OUTPUT, RESTART = (
    "discretisation and run",
    "friction (2-D and 3-D problems: the tangential components are the ones other than the constrained one)",
    "contact treatment and scheme parameters (docs/methods.md)", "output", "configuration and restart")
GROUPS = (RUN, FRICTION, METHOD, OUTPUT, RESTART)


def _check_pair(value: Any, label: str) -> list[str]:
    if isinstance(value, Pair) or (isinstance(value, str) and value in PAIRS):
        return []
    return [f"unknown pair {value!r}; choose one of {', '.join(PAIRS)}"]


_LINEAR_HELP = (
    "linear solves of the semi-smooth Newton: auto = schur, or amg above 10000 constrained dofs, or in 3-D "
    "cg-pmg (W^h = P2) or cg-gamg when a factorisation would not fit in memory (default); schur = one factorisation of the step "
    "matrix per run, the active set by a small dense Schur complement of cached columns K^-1 e_i; cg-factor = "
    "one factorisation, CG on the inactive set; lu = refactorise at every Newton iteration; amg = CG + "
    "BoomerAMG on the reduced matrix (set up when the active set changes); cg-amg = CG on the inactive set "
    "with one BoomerAMG set-up of the step matrix; cg-gamg = CG on the inactive set with one GAMG set-up "
    "(rigid body modes), no factorisation; cg-pmg = CG on the inactive set with one two-level P2 -> P1 multigrid "
    "(Chebyshev smoothing, GAMG on P1), no factorisation, P2 only")
_POSITIVE: dict[str, Any] = dict(type=float, low=0.0, low_strict=True, expect="a positive finite number")
_COUNT: dict[str, Any] = dict(type=int, low=1, expect="an integer >= 1", metavar="K")

#: the options of every run (``{choices}``, ``{default}``, ``{unit}`` in a help are filled in by
#: the command line, the default being the problem's where it declares one)
TABLE = (
    RunOption("pair", "P1+/P0", "(W^h, H^h) pair: {choices} (default {default})", type=str,
              choices=lambda: tuple(PAIRS), metavar="PAIR", noun="pair", group=RUN, identity=True,
              problem_default=True, validate=_check_pair),
    RunOption("mass", None, "C treatment: diagonal (P0), lumped or consistent (P1 velocity; consistent solves the "
                            "(U, V) block system), standard (H = W); default: diagonal for P0, lumped for P1",
              type=str, choices=MASS_TREATMENTS, noun="mass", group=RUN, identity=True),
    RunOption("scheme", "midpoint", "time scheme (default {default})", type=str, choices=schemes.names,
              noun="scheme", group=RUN, identity=True, problem_default=True),
    RunOption("dt", 1e-3, "time step (default {default}{unit})", **_POSITIVE, group=RUN, identity=True,
              problem_default=True),
    RunOption("T", 0.8, "final time (default {default}{unit})", **_POSITIVE, group=RUN, problem_default=True),
    RunOption("vi_solver", "ssn", "step solver: ssn = semi-smooth Newton / primal-dual active set (default), or "
                                  "PETSc SNES vinewtonrsls / vinewtonssls", type=str,
              choices=lambda: tuple(VI_SOLVERS), noun="step solver", group=RUN, identity=True),
    RunOption("linear", "auto", _LINEAR_HELP, type=str, choices=LINEAR_STRATEGIES, noun="linear strategy",
              group=RUN, identity=True),
    RunOption("quadrature_degree", None,
              f"quadrature degree of every form: auto = UFL's exact estimate on affine simplices, "
              f"{quadrature.CURVED_DEGREE} on curved cells (the disc's P2 geometry: entries converged to round-off; "
              f"default); {quadrature.ESTIMATED} = UFL's estimate everywhere (runs before this option); or an "
              f"integer from 1 to {quadrature.MAX_DEGREE}", metavar="Q", group=RUN,
              parse_text=quadrature.parse, validate=quadrature.check, toml=(int, str),
              toml_expected=f"an integer, {quadrature.AUTO!r} or {quadrature.ESTIMATED!r}"),
    RunOption("material", "linear", "the body's material: linear (the problem's a(u, w): small strains, default), svk "
                                    "(Saint Venant-Kirchhoff), neo-hookean (compressible) or problem (the problem's "
                                    "strain_energy(C)): total Lagrangian finite strain with the energy-momentum "
                                    "midpoint scheme (docs/finite_strain.md)", type=str, choices=materials.names,
              noun="material", group=RUN, identity=True, problem_default=True),
    RunOption("newton", "full", "the tangent of a hyperelastic material's step: full (a new one at every Newton "
                                "iteration, default), modified (the step's first: one factorisation per step) or "
                                "initial (the linear step matrix, the tangent at rest: one factorisation per run)",
              type=str, choices=("full", "modified", "initial"), noun="newton", group=RUN, identity=True),
    RunOption("friction", None, "friction at the constrained vertices (default none): coulomb = |lam_T| <= mu lam_N; "
                                "tresca = |lam_T| <= threshold x the vertex's boundary measure at every constrained "
                                "vertex, in contact or not (for a body in lasting contact)", type=str,
              choices=lambda: _friction.LAWS, noun="friction law", group=FRICTION),
    RunOption("constrain", "vertices", "where the constraint holds: vertices (eq. (13), default), nodes (every dof "
                                       "of W^h on the constrained boundary: P2 mid-edge nodes too) or weighted (the "
                                       "gap averaged around each vertex: holds a P2 face between its vertices)",
              type=str,
              choices=CONSTRAIN, noun="constrain", group=METHOD),
    RunOption("contact", "exact", "contact treatment: {choices}; exact = the variational inequality (default)",
              type=str, choices=contact.names, noun="contact treatment", group=METHOD),
    RunOption("write_every", None, "write the XDMF fields every K steps (default 10)", **_COUNT, group=OUTPUT),
    RunOption("checkpoint_every", None, "write DIR/checkpoint.npz every K steps (a SIGINT/SIGTERM always writes one)",
              **_COUNT, group=RESTART, restart=True),
)
_TABLE = {p.name: p for p in TABLE}
#: options a restart may change (the others are the run's)
RESTART_MAY_CHANGE = tuple(p.name for p in TABLE if p.restart)
#: options a checkpoint must agree with (the run's identity)
IDENTITY = tuple(p.name for p in TABLE if p.identity)
#: the keyword of each owner's group of options, and the command-line group of its options
OWNER_KINDS = {"friction": ("friction_options", FRICTION), "contact": ("contact_options", METHOD),
               "scheme": ("scheme_options", METHOD)}
#: the longest run accepted (T / dt): ~100 bytes of time series per step in memory
MAX_STEPS = 1e7
#: T must be a whole number of steps of dt, to this relative tolerance
STEP_RTOL = 1e-9


def _owners(kind: str) -> tuple[str, ...]:
    owners: dict[str, Callable[[], tuple[str, ...]]] = {
        "scheme": schemes.names, "contact": contact.names, "friction": lambda: _friction.LAWS}
    return owners[kind]()


def options_of(kind: str, owner: str) -> tuple[Param, ...]:
    """The options the ``kind`` (``"scheme"``, ``"contact"``, ``"friction"``) ``owner`` declares."""
    if kind == "scheme":
        return tuple(schemes.get(owner).options)
    return tuple(contact.options_of(owner) if kind == "contact" else _friction.options_of(owner))


def _owned() -> dict[str, tuple[str, str, Param]]:
    """name -> (kind, owner, Param) of every option the registered schemes, contact treatments
    and friction laws declare (RunInputError when two declare one name)."""
    out: dict[str, tuple[str, str, Param]] = {}
    for kind in OWNER_KINDS:
        for owner in _owners(kind):
            for p in options_of(kind, owner):
                if p.name in out or p.name in _TABLE:
                    first = f"{out[p.name][0]} {out[p.name][1]}" if p.name in out else "every run"
                    raise RunInputError(f"run option {p.name!r} is declared by {first} and by {kind} {owner}: "
                                        f"rename one")
                out[p.name] = (kind, owner, p)
    return out


def declarations() -> tuple[RunOption, ...]:
    """Every run option now: :data:`TABLE`, then the options of every registered scheme,
    contact treatment and friction law (``owner`` set, the group of their kind)."""
    fields = [f.name for f in dataclasses.fields(Param)]
    owned = [RunOption(**{f: getattr(p, f) for f in fields}, owner=(kind, owner), group=OWNER_KINDS[kind][1])
             for kind, owner, p in _owned().values()]
    return (*TABLE, *owned)


def names() -> tuple[str, ...]:
    """Every run option's name (``run.json``'s ``run_options`` keys)."""
    return tuple(p.name for p in declarations())


def complete(given: Mapping[str, Any], problem_defaults: Optional[Mapping[str, Any]] = None) -> dict[str, Any]:
    """Every run option: ``given`` (flat), else the problem's declared default (the options
    declared ``problem_default``), else the table's (None for a method's options: its owner's)."""
    out = {p.name: None if p.owner else p.default for p in declarations()}
    out.update({k: v for k, v in dict(problem_defaults or {}).items() if k in _TABLE and _TABLE[k].problem_default})
    out.update(given)
    return out


def collect(given: Mapping[str, Any], where: str = "simulate", stacklevel: int = 3) -> dict[str, Any]:
    """The flat run options (``run.json``'s names) of the keywords ``given`` to ``where``
    (simulate or plan; None values are not given): the table's options as they are, the groups
    (``scheme_options``, ...) opened. The flat spelling of a method's option (``mu=0.3``) is a
    deprecated alias: a FutureWarning names the grouped one.

    Raises:
        RunInputError: an unknown keyword, an option in another owner's group, one given twice.
    """
    owned, groups = _owned(), {kw: kind for kind, (kw, _) in OWNER_KINDS.items()}
    flat: dict[str, Any] = {}
    errors: list[str] = []
    unknown: list[str] = []

    def put(name: str, value: Any) -> None:
        if name in flat:
            errors.append(f"{name} is given twice (as {name}= and in {owned[name][0]}_options)")
        elif value is not None:
            flat[name] = value

    for key, value in given.items():
        if key in groups:
            errors += _open_group(key, groups[key], value, owned, put)
        elif key in _TABLE:
            if value is not None:
                flat[key] = value
        elif key in owned:
            kw = OWNER_KINDS[owned[key][0]][0]
            warnings.warn(f"{where}({key}=...) is deprecated: write {kw}={{{key!r}: ...}}", FutureWarning,
                          stacklevel=stacklevel)
            put(key, value)
        else:
            unknown.append(key)
    if unknown:
        errors.insert(0, f"unknown run option(s) {', '.join(sorted(unknown))}; the run options: "
                         f"{', '.join([*_TABLE, *(kw for kw, _ in OWNER_KINDS.values())])}")
    if errors:
        raise RunInputError("; ".join(errors))
    return flat


def _open_group(keyword: str, kind: str, value: Any, owned: Mapping[str, tuple[str, str, Param]],
                put: Callable[[str, Any], None]) -> list[str]:
    """Messages for the group ``keyword`` (e.g. ``scheme_options``) of ``kind``; its options go to ``put``."""
    if value is None:
        return []
    if not isinstance(value, Mapping):
        return [f"{keyword} must be a dict of option: value (got {type(value).__name__})"]
    errors = []
    for name, v in value.items():
        if name in owned and owned[name][0] == kind:
            put(name, v)
        elif name in owned:
            other, owner, _ = owned[name]
            errors.append(f"{name} is a parameter of {other} {owner}: give it in {OWNER_KINDS[other][0]}, "
                          f"not in {keyword}")
        elif name in _TABLE:
            errors.append(f"{name} is an option of every run, not of a {kind}: give it as {name}=")
        else:
            mine = [n for n, (k, _, _) in owned.items() if k == kind]
            errors.append(f"unknown {kind} option {name!r} in {keyword}; the {kind} options: "
                          f"{', '.join(mine) or 'none'}")
    return errors


def grouped(flat: Mapping[str, Any]) -> dict[str, Any]:
    """The keywords of :func:`~sdm_dolfinx.run.simulate` for flat run options (``run.json``'s
    ``run_options``, a TOML file, the command line): each option of a scheme, contact treatment
    or friction law in its group; None values left out."""
    owned = _owned()
    out: dict[str, Any] = {}
    for k, v in flat.items():
        if v is None:
            continue
        if k in owned:
            out.setdefault(OWNER_KINDS[owned[k][0]][0], {})[k] = v
        else:
            out[k] = v
    return out


def method_names() -> tuple[str, ...]:
    """The options of the method group (where K^h acts, the contact treatment, the schemes' and
    treatments' options): recorded at the top of ``run.json`` when they differ from the default."""
    return tuple(p.name for p in declarations() if p.group == METHOD)


def check(o: Mapping[str, Any], cli: bool = False) -> None:
    """Every message refusing the complete flat run options ``o`` (:func:`complete`), joined in
    one RunInputError: each option against its declaration, a method's option given to another
    method (it would be ignored), and the rules between options. ``cli``: name the options as the
    command line spells them."""
    label: Callable[[Param], str] = (lambda p: f"--{p.option}") if cli else (lambda p: p.name)
    errors: list[str] = []
    decl = declarations()
    for p in decl:
        if p.owner is None:
            errors += p.check(o.get(p.name), label(p))
    for p in decl:
        if p.owner is not None:
            errors += _owned_errors(p, p.owner, o, label(p))
    errors += _rules(o, {p.name: label(p) for p in decl})
    if errors:
        raise RunInputError("; ".join(errors))


def _owned_errors(p: RunOption, owned_by: tuple[str, str], o: Mapping[str, Any], label: str) -> list[str]:
    """The one rule of a method's option (``p``, of ``owned_by``: its ``owner``): given to its
    owner only, then checked by its declaration."""
    kind, owner = owned_by
    chosen = o.get(kind) or ("none" if kind == "friction" else None)
    value = o.get(p.name)
    if chosen != owner:
        return [] if value is None else [f"{label} is a parameter of {kind} {owner}, not of {kind} {chosen}: "
                                         f"remove it or choose {kind} {owner}"]
    if value is None:
        return [f"{kind} {owner} needs {label}"] if p.required else []
    return p.check(value, label)


def _rules(o: Mapping[str, Any], label: Mapping[str, str]) -> list[str]:
    """Messages for combinations of options that cannot run together."""
    errors: list[str] = _time_rules(o.get("T"), o.get("dt"), label)
    pair, mass = o.get("pair"), o.get("mass")
    if mass is not None and pair is not None and not _check_pair(pair, "pair"):
        pair = get_pair(pair) if isinstance(pair, str) else pair
        if mass in MASS_TREATMENTS and mass not in pair.allowed_masses():
            errors.append(f"mass {mass} is not available for {pair.name}; choose {', '.join(pair.allowed_masses())}")
    scheme = o.get("scheme")
    if scheme in schemes.names() and schemes.get(scheme).stateful and o.get("checkpoint_every") is not None:
        errors.append(f"{label['checkpoint_every']} must be left out with scheme {scheme}: it keeps state between "
                      f"steps that a checkpoint does not hold (it cannot restart)")
    if o.get("friction") in _friction.LAWS:
        errors += _friction.check_solver(o.get("friction"), o.get("vi_solver"), o.get("linear"))
    errors += solver_rules.treatment_solver(o, label) or solver_rules.snes_linear(o, label)
    if o.get("newton") in ("modified", "initial") and materials.is_linear(o.get("material")):    # ignored
        errors.append(f"{label['newton']} {o['newton']} is the tangent of a hyperelastic material's step; "
                      f"{label['material']} linear has a constant step matrix: remove {label['newton']}")
    missing = missing_package(o.get("linear"))
    if missing and o.get("vi_solver") in (None, "ssn"):
        errors.append(f"{label['linear']} {o['linear']} {missing}")
    return errors


#: the command line's own options besides the run options (the run commands' and inspect's,
#: cli/run.py, cli/inspect.py): no problem parameter may be named like one of these or a run option
COMMAND_LINE_NAMES = ("out", "overwrite", "quiet", "config", "restart", "allow_changed_source", "problem",
                      "problem_file", "help", "sweep", "coulomb_bound", "json", "png", "tol", "dense_max")


def reserved_names() -> tuple[str, ...]:
    """The names no problem parameter may take: every run option (the registered methods' too)
    and :data:`COMMAND_LINE_NAMES` (a parameter's ``--option`` and TOML key would clash with them)."""
    return (*names(), *COMMAND_LINE_NAMES)


def check_problem_names(spec: Any) -> None:
    """RunInputError naming the problem's file (or name) and the clash when one of ``spec``'s
    parameters is named like a run option or an option of the command line."""
    runs = {p.name: p.option for p in declarations()}
    where = f"problem file {spec.source}" if spec.source else f"problem {spec.name!r}"
    for p in spec.params:
        for name in dict.fromkeys((p.name, p.option.replace("-", "_"))):
            if name in runs:
                clash = f"the run option --{runs[name]}"
            elif name in COMMAND_LINE_NAMES:
                clash = f"the command line's --{name.replace('_', '-')}"
            else:
                continue
            raise RunInputError(f"{where}: parameter {p.name!r} (--{p.option}) is named like {clash}: rename it "
                                f"(docs/add_a_problem.md lists the reserved names)")


def check_time(T: Any, dt: float, cli: bool = False) -> None:
    """RunInputError when the final time ``T`` is refused with the time step ``dt`` (a restart
    extending a run to a later T: the other options are the run's, checked when it started)."""
    label = {p.name: f"--{p.option}" if cli else p.name for p in TABLE}
    errors = _TABLE["T"].check(T, label["T"]) or _time_rules(T, dt, label)
    if errors:
        raise RunInputError("; ".join(errors))


def _time_rules(T: Any, dt: Any, label: Mapping[str, str]) -> list[str]:
    """Messages for a final time ``T`` that the time step ``dt`` cannot reach in whole steps."""
    if _TABLE["dt"].complaints(dt) or _TABLE["T"].complaints(T):
        return []
    if T < dt:
        return [f"{label['T']} ({T}) must be >= {label['dt']} ({dt})"]
    if T / dt > MAX_STEPS:
        return [f"T / dt = {T / dt:.3g} steps: at most {MAX_STEPS:.0e} (the time series alone would take "
                f"{T / dt * 100 / 1e9:.3g} GB)"]
    return _check_whole_steps(T, dt)


def _check_whole_steps(T: float, dt: float) -> list[str]:
    """A message when T is not a whole number of steps of dt (relative tolerance
    :data:`STEP_RTOL`): the run would silently stop short of T. The steps are counted as the
    run counts them (:func:`~sdm_dolfinx.run.result.num_steps`), so T = 0.02, dt = 1e-4
    (200.00000000000003 steps in floating point) is 200 steps and accepted."""
    n = num_steps(T, dt)
    if abs(n * dt - T) <= STEP_RTOL * T:
        return []
    return [f"T = {num(T)} is not a multiple of dt = {num(dt)}: {n} steps end at t = {num(n * dt)}; give "
            f"T = {num(n * dt)} or {num((n + 1) * dt)}"]


def num(x: float) -> str:
    """A time for messages: 0.009, not 0.009000000000000001."""
    return f"{x:.12g}"

