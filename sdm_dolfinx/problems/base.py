"""The Problem (what is solved) and its declaration (which parameters make one).

A :class:`Problem` is data (a mesh, UFL forms, Dirichlet data, the constrained vertices and
their bounds, initial conditions, a probe point). Nothing downstream knows which problem
runs: the membrane of the paper's section 4 and the disc of section 5 are two Problems, and
a user-defined problem is a third (``docs/add_a_problem.md``).

A :class:`ProblemSpec` declares a family of Problems once: its parameters (:class:`Param`:
default, unit, bounds, help; the declaration run options share, :mod:`sdm_dolfinx.params`) and
a ``build(comm, **values)`` function. The command line's options, the TOML keys, ``run.json``
and the rebuilding of a finished run for post-processing all come from that declaration, for
the built-in problems and a user's problem file alike.
"""
from __future__ import annotations

import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional, Union

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from sdm_dolfinx import compat
from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.params import PARAM_TYPES as PARAM_TYPES  # noqa: F401  (declared once for problems and runs)
from sdm_dolfinx.params import Param as Param
from sdm_dolfinx.problems.dirichlet import DirichletPart as DirichletPart
from sdm_dolfinx.problems.dirichlet import MeshEntities as MeshEntities
from sdm_dolfinx.problems.dirichlet import validate_parts
from sdm_dolfinx.problems import constraint_checks as _checks
from sdm_dolfinx.problems import density as _density
from sdm_dolfinx.problems.contact_pairs import ContactPair as ContactPair
from sdm_dolfinx.problems import bodies as _bodies
from sdm_dolfinx.problems.bodies import Body as Body
from sdm_dolfinx.problems.errors import ProblemInputError as ProblemInputError
from sdm_dolfinx.problems.mesh_checks import degenerate_cells

if TYPE_CHECKING:
    from dolfinx.fem import Constant
    from dolfinx.mesh import Mesh

#: a UFL expression or form (ufl has no annotations)
UFL = Any
#: ``x -> values`` at the points x of shape (3, n), as ``Function.interpolate`` takes it
PointFunction = Callable[[npt.NDArray[np.float64]], npt.ArrayLike]


#: the time-series columns a Problem may add (``extra_columns``): sum of the normal multipliers,
#: e_x^T M Vbar, the momentum along ``momentum_component``, 1/2 U^T A U
EXTRA_COLUMNS = ("contact_force", "momentum_x", "momentum_y", "elastic")

#: ``Problem.u0`` asking for the equilibrium start (:mod:`sdm_dolfinx.method.equilibrium`)
EQUILIBRIUM = "equilibrium"


@dataclass
class Problem:
    """A problem  M u'' + A u ∈ L − N_K(u)  in the sense of the paper's eq. (1)–(2).

    Attributes:
        name: short name, used in file names and ``run.json``.
        mesh: a dolfinx mesh (already distributed).
        shape: value shape of u: ``()`` for a scalar field, ``(gdim,)`` for a vector field.
        a: ``a(u, w)`` -> UFL bilinear form (the operator A).
        l: ``l(w)`` -> UFL linear form (the load L, gravity included).
        rho: density: the mass forms are ``rho * u.w dx``; a number, or a dolfinx Function on the mesh (a
            DG0 density per cell: bodies of different densities in one mesh; :mod:`.density`).
        u0: initial displacement: a callable ``x -> values`` or a ``fem.Function`` on the mesh (any
            element: interpolated into W^h), as ``Function.interpolate`` takes them; or
            :data:`EQUILIBRIUM` (``"equilibrium"``): the static solution of the run's own
            discretisation under L(0) with the constraint (its kind), Dirichlet data and the run's
            friction sticking (:mod:`sdm_dolfinx.method.equilibrium`).
        v0: initial velocity, same form.
        constraint_vertices: ``mesh -> local vertex indices`` where K^h acts (eq. (13)); None with
            ``contact_pairs``.
        lower_bound: ``x (3, n) -> (n,)`` the bound on the constrained displacement
            component at vertices of coordinates x: u_c(a_i) >= lower_bound(a_i); with
            ``moving_bound`` it is ``(x, t) -> (n,)``, the bound at the time t.
        moving_bound: the obstacle moves along the constrained component: ``lower_bound`` takes
            ``(x, t)`` (a rising floor, a wall moving at V: ``lambda x, t: V * t - x[0]``). Each
            step imposes the bound of the step, :meth:`Scheme.step_bound
            <sdm_dolfinx.schemes.base.Scheme.step_bound>`: the midpoint scheme constrains
            U^{n+1/2} >= (g(t_n) + g(t_{n+1})) / 2 (the mean of the bounds, which keeps a vertex
            in sustained contact on the obstacle at every t_n, so that E - obstacle_work is
            conserved: :mod:`sdm_dolfinx.schemes.midpoint`), backward Euler U^{n+1} >= g(t_{n+1});
            the other schemes, the penalty and Nitsche treatments refuse it in one line. The time
            series gets the columns ``obstacle_work`` and ``obstacle_probe``.
        obstacles: rigid obstacles (:mod:`sdm_dolfinx.obstacles`: half-spaces of any
            orientation, balls and bowls, cylinders, wedges, surface meshes; fixed or moving) instead
            of ``lower_bound``, which is then None: every constrained node stays outside every
            obstacle, phi(a_i + u(a_i), t) >= 0, the rows linearised at the current configuration
            (:mod:`sdm_dolfinx.method.obstacle_rows`). A vector u only. Taken by the midpoint and
            backward Euler schemes with the exact contact, frictionless (the rest refuse it in one line).
        contact_pairs: contact between the bodies of the mesh (:class:`ContactPair`: the slave
            facets' vertices stay outside the master facets' body; :mod:`.contact_pairs`), instead
            of ``constraint_vertices``, ``lower_bound`` and ``obstacles``. Frictionless, midpoint
            and backward Euler schemes, the exact contact (the rest refuse it in one line).
        bodies: the bodies of a mesh of several (:class:`Body`: a name and its cells), for the
            per-body columns: momentum, kinetic and elastic energy of each (:mod:`.bodies`).
        constraint_component: component of u that is bounded, and that ``u_probe`` records:
            required for a vector u (an int in 0..gdim-1; the Problem refuses None), None (or 0)
            for a scalar u.
        constraint_measure: ``q -> UFL form`` of the P1 test function q; its value at a
            vertex is that vertex's lumped measure, so stress = nodal multiplier / measure.
        dirichlet_facets: ``mesh -> local facet indices`` with u = dirichlet_value, or None.
        dirichlet_value: callable ``x -> values``, constant in time (a run whose
            ``dirichlet_value`` changes stops with an error): data that move, or whose reaction
            force is wanted, are declared as ``dirichlet_parts``.
        dirichlet_parts: named boundary parts with prescribed, possibly time-dependent, data
            u = u_D(x, t) on some or all components (:class:`DirichletPart`); each adds its
            reaction columns and the run the column ``dirichlet_work`` (docs/outputs.md). Taken
            by the midpoint and backward Euler schemes (the others refuse them in one line).
        probe: the point (x, y) where the displacement (and, at the nearest constrained
            vertex, the contact stress) is recorded.
        extra_columns: additional time-series columns among :data:`EXTRA_COLUMNS`:
            ``contact_force``, ``momentum_x``, ``momentum_y``, ``elastic`` (1/2 U^T A U).
        parameters: physical parameters for ``run.json``; ``units`` their units.
        momentum_component: for ``momentum_y``: the component index used.
        args: the declared parameter values it was built from (set by
            :meth:`ProblemSpec.problem`; empty for a Problem built by hand).
        source: the problem file that declared it (None for a built-in problem).
        source_sha256: the SHA-256 of that file when it was loaded (a restart refuses a changed file).
        time: a scalar ``fem.Constant`` that ``l(w)`` may use as the time t, or None. When
            given, the load is time-dependent: L is reassembled before every step with
            ``time`` set to the time at which the scheme evaluates the load (midpoint:
            t_{n+1/2}, backward Euler: t_{n+1}) and, for the energies, to the time of the
            state. Without it L is assembled once, and a Constant or Function of ``l(w)`` (or
            of ``a(u, w)``, always) that changes during the run stops the run with an error.
            The potential energy is then 1/2 U^T A U - U^T L(t): with a time-dependent load the
            energy changes by the work of the load's change.
        stress: ``stress(u)`` -> UFL, the Cauchy stress sigma(u) of a vector u (a (gdim, gdim)
            tensor) or the flux vector of a scalar u, such that a(u, w) = int sigma(u) : grad w dx
            (the Nitsche contact treatment's boundary term sigma(u) n . n); None when the
            problem declares none (Nitsche is then refused in one line). The membrane has none
            on purpose: its constraint acts inside the domain, where Nitsche's boundary term
            has no meaning.
        strain_energy: ``strain_energy(C)`` -> UFL, a hyperelastic strain energy density psi of the right
            Cauchy-Green tensor C = F^T F (a (gdim, gdim) tensor; plane strain in 2-D), which the run option
            ``material problem`` takes (:mod:`sdm_dolfinx.materials`); it must linearise at C = I to
            ``a(u, w)`` (checked at set-up). None: the built-in materials only.

    The constrained boundary, where the time series' ``gap_min_boundary`` looks at every dof
    of W^h (P2 mid-edge nodes included, which the vertex constraint (13) does not hold), is
    made of the mesh facets whose vertices are all constrained.
    """
    name: str
    mesh: Mesh
    shape: tuple[int, ...]
    a: Callable[[UFL, UFL], UFL]
    l: Callable[[UFL], UFL]
    u0: Union[PointFunction, str]
    v0: PointFunction
    constraint_vertices: Optional[MeshEntities]
    lower_bound: Optional[PointFunction]
    constraint_measure: Callable[[UFL], UFL]
    rho: Any = 1.0
    constraint_component: Optional[int] = None
    dirichlet_facets: Optional[MeshEntities] = None
    dirichlet_value: Optional[PointFunction] = None
    probe: Sequence[float] = (0.0, 0.0)
    extra_columns: tuple[str, ...] = ()
    parameters: dict[str, Any] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    momentum_component: int = 1
    args: dict[str, Any] = field(default_factory=dict)
    source: Optional[str] = None
    source_sha256: Optional[str] = None
    time: Optional[Constant] = None
    stress: Optional[Callable[[UFL], UFL]] = None
    dirichlet_parts: Sequence[DirichletPart] = ()
    moving_bound: bool = False
    obstacles: Sequence[Any] = ()
    contact_pairs: Sequence[ContactPair] = ()
    bodies: Sequence[Body] = ()
    strain_energy: Optional[Callable[[UFL], UFL]] = None

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Refuse, in one line naming the problem, what downstream would otherwise guess.

        Raises:
            ProblemInputError: a vector u without ``constraint_component`` (or one out of
                range), a scalar u with a component other than 0, a ``time`` that is not a
                scalar Constant, a ``stress`` that is not callable.
        """
        shape, comp = tuple(self.shape), self.constraint_component
        if shape:
            if comp is None:
                raise ProblemInputError(
                    f"problem {self.name!r}: a vector problem must name constraint_component, the component "
                    f"of u bounded at the constrained vertices (and recorded by u_probe; with contact_pairs only "
                    f"the latter), e.g. constraint_component=1 for u_y")
            if isinstance(comp, bool) or not isinstance(comp, (int, np.integer)) or not 0 <= comp < shape[0]:
                raise ProblemInputError(f"problem {self.name!r}: constraint_component must be an integer in "
                                        f"0..{shape[0] - 1} for u of shape {shape} (got {comp!r})")
        elif comp not in (None, 0):
            raise ProblemInputError(f"problem {self.name!r}: a scalar problem has no component {comp!r}; "
                                    f"leave constraint_component at None")
        if (isinstance(self.u0, str) and self.u0 != EQUILIBRIUM) or not (isinstance(self.u0, str)
                                                                         or callable(self.u0)
                                                                         or hasattr(self.u0, "function_space")):
            raise ProblemInputError(f"problem {self.name!r}: u0 must be x -> values, a dolfinx Function or "
                                    f"{EQUILIBRIUM!r} (the static equilibrium), not {self.u0!r}")
        unknown = [c for c in self.extra_columns if c not in EXTRA_COLUMNS]
        if unknown:
            raise ProblemInputError(f"problem {self.name!r}: unknown extra_columns {', '.join(map(repr, unknown))}; "
                                    f"choose among {', '.join(EXTRA_COLUMNS)}")
        if self.stress is not None and not callable(self.stress):
            raise ProblemInputError(f"problem {self.name!r}: stress must be a callable u -> sigma(u) (UFL), or None "
                                    f"(got {type(self.stress).__name__})")
        if self.strain_energy is not None and not callable(self.strain_energy):
            raise ProblemInputError(f"problem {self.name!r}: strain_energy must be a callable C -> psi(C) (UFL), or "
                                    f"None (got {type(self.strain_energy).__name__})")
        if self.time is not None and (not hasattr(self.time, "value") or np.shape(self.time.value) != ()):
            raise ProblemInputError(f"problem {self.name!r}: time must be a scalar fem.Constant used by l(w) "
                                    f"(got {type(self.time).__name__})")
        validate_parts(self.name, self.dirichlet_parts, shape)
        _checks.validate_obstacles(self)
        _checks.validate_pairs(self)
        _bodies.validate(self)
        if not isinstance(self.moving_bound, (bool, np.bool_)):
            raise ProblemInputError(f"problem {self.name!r}: moving_bound must be True (lower_bound takes (x, t)) or "
                                    f"False (lower_bound takes x) (got {self.moving_bound!r})")
        _density.validate(self)
        degenerate = degenerate_cells(self.mesh) if hasattr(self.mesh, "geometry") else None
        if degenerate:
            raise ProblemInputError(f"problem {self.name!r}: {degenerate}")

    def describe(self) -> dict[str, Any]:
        """Parameters with their units, as written to ``run.json`` (``args`` and ``source``
        are what :func:`sdm_dolfinx.problems.rebuild` needs)."""
        d: dict[str, Any] = {"name": self.name, "parameters": dict(self.parameters), "units": dict(self.units),
             "probe": [float(c) for c in np.asarray(self.probe)]}
        if self.args:
            d["args"] = dict(self.args)
        if self.source:
            d["source"] = self.source
            d["source_sha256"] = self.source_sha256
        if isinstance(self.u0, str):
            d["start"] = "equilibrium (static solution of the run's discretisation under L(0))"
        if self.time is not None:
            d["load"] = "time-dependent (reassembled every step at the scheme's load time)"
        if self.dirichlet_parts:
            d["dirichlet_parts"] = [part.describe(tuple(self.shape)) for part in self.dirichlet_parts]
        if self.moving_bound:
            d["bound"] = "moving: lower_bound(x, t) (each step imposes the scheme's step bound)"
        if self.contact_pairs:
            d["contact_pairs"] = [pair.describe() for pair in self.contact_pairs]
        if self.bodies:                     # the XDMF's cell field ``body`` numbers them from 1 in this order
            d["bodies"] = [b.name for b in self.bodies]
        if self.obstacles:
            d["obstacles"] = [o.describe() if hasattr(o, "describe") else {"kind": type(o).__name__}
                              for o in self.obstacles]
        return d

    def bound(self, x: npt.NDArray[np.float64], t: float = 0.0) -> npt.ArrayLike:
        """The bound ``lower_bound`` at the points x (3, n) at the time t (:func:`bound_at`)."""
        return bound_at(self, x, t)


def bound_at(problem: Any, x: npt.NDArray[np.float64], t: float = 0.0) -> npt.ArrayLike:
    """``problem.lower_bound`` at the points x (3, n) at the time t: ``lower_bound(x, t)`` for a moving
    bound (``moving_bound``), else ``lower_bound(x)`` (t not used)."""
    values: npt.ArrayLike = problem.lower_bound(x, t) if getattr(problem, "moving_bound", False) \
        else problem.lower_bound(x)
    return values


def label(problem: Any) -> str:
    """How messages name a problem: its file (``problem file /path/my_block.py``), else its name."""
    source = getattr(problem, "source", None)
    return f"problem file {source}" if source else f"problem {problem.name!r}"


def one_line(e: BaseException) -> str:
    """``Type: message`` of an exception on one line (its first non-empty line)."""
    text = next((ln.strip() for ln in str(e).splitlines() if ln.strip()), "")
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def user_line(e: BaseException, path: Union[str, Path]) -> str:
    """``, line N`` of the innermost frame of ``e``'s traceback in the file ``path`` ('' if none)."""
    frames = [f for f in traceback.extract_tb(e.__traceback__) if Path(f.filename).resolve() == Path(path)]
    if isinstance(e, SyntaxError) and e.lineno and Path(e.filename or "").resolve() == Path(path):
        return f", line {e.lineno}"
    return f", line {frames[-1].lineno}" if frames else ""


@dataclass
class ProblemSpec:
    """The declaration of a problem: its parameters once, and how to build it.

    Attributes:
        name: the problem's name (the command ``python -m sdm_dolfinx NAME``, ``run.json``).
        build: ``build(comm, **values) -> Problem`` with every declared parameter given.
        params: the :class:`Param` declarations, in the order of ``--help``.
        doc: the description; its first line is the command's one-line help.
        defaults: run defaults: ``pair``, ``scheme``, ``dt``, ``T`` and ``time_unit``.
        check: ``check(values, label) -> [messages]`` for conditions between parameters
            (``label(name)`` spells a parameter as :meth:`label` does), beyond each
            parameter's own bounds.
        estimate: ``estimate(values) -> {"vertices", "edges", "cells", "value_size", "by"}``,
            the mesh the values make, counted without building it (``by``: the parameters
            that set its size, for messages), or None; the run's memory is estimated from it
            and a run that would not fit is refused before it starts
            (:func:`sdm_dolfinx.run.memory.estimate_memory`).
        source: the file that declared it (None for a built-in problem).
        source_sha256: the SHA-256 of that file when it was loaded.
        exact: ``exact(problem) -> ExactSolution`` for a problem with a closed form (the
            comparison of methods measures errors against it), or None: an object with
            ``displacement(x, t)``, ``velocity(x, t)``, ``strain(x, t)`` (x of shape (3, n)
            as dolfinx gives it; vectorised), ``contact_stress(t)`` (>= 0 when the obstacle
            pushes), ``contact_intervals`` ([(t_start, t_end), ...]), ``intervals(T)``,
            ``energy``, ``contact_point`` (:class:`sdm_dolfinx.problems.exact.ExactSolution`).
    """
    name: str
    build: Callable[..., Problem]
    params: Sequence[Param]
    doc: str = ""
    defaults: dict[str, Any] = field(default_factory=dict)
    check: Optional[Callable[[dict[str, Any], Callable[[str], str]], Iterable[str]]] = None
    estimate: Optional[Callable[[dict[str, Any]], dict[str, Any]]] = None
    source: Optional[str] = None
    source_sha256: Optional[str] = None
    exact: Optional[Callable[[Problem], Any]] = None

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(name)

    def values(self, given: Optional[Mapping[str, Any]] = None, cli: bool = False) -> dict[str, Any]:
        """Every declared parameter's value: the defaults, overridden by ``given``.

        Raises:
            ProblemInputError: an unknown name, or values out of type or bounds (every
                message, joined with '; '); labels are ``--option`` when ``cli``.
        """
        given = dict(given or {})
        names = [p.name for p in self.params]
        unknown = [k for k in given if k not in names]
        if unknown:
            raise ProblemInputError(f"{self.name} has no parameter {', '.join(map(repr, unknown))}; "
                                    f"its parameters: {', '.join(names)}")
        errors: list[str] = []
        values: dict[str, Any] = {}
        for p in self.params:
            v = given.get(p.name, p.default)
            msgs = p.check(v, self.label(p.name, cli))
            errors += msgs
            values[p.name] = v if msgs else p.convert(v)
        if not errors and self.check is not None:
            errors += list(self.check(values, lambda n: self.label(n, cli)))
        if errors:
            raise ProblemInputError("; ".join(errors))
        return values

    def label(self, name: str, cli: bool = False) -> str:
        """How a parameter is named in messages: ``--option`` on the command line, else its name."""
        return f"--{self.param(name).option}" if cli else name

    def problem(self, comm: MPI.Comm = MPI.COMM_WORLD, **given: Any) -> Problem:
        """The Problem for these parameter values (the others at their defaults)."""
        values = self.values(given)
        where = f"problem file {self.source}" if self.source else f"problem {self.name!r}"
        if self.source is None:
            prob = self.build(comm, **values)
        else:
            try:
                prob = self.build(comm, **values)
            except ProblemInputError as e:      # its Problem refused (rho, cells, ...): name the file too
                raise ProblemInputError(f"{where}{user_line(e, self.source)}: {e}") from None
            except Exception as e:      # a bug in the user's file: one line naming the file and line
                raise ProblemInputError(f"{where}{user_line(e, self.source)}: building "
                                        f"{self.name!r} failed: {one_line(e)}") from None
        if not isinstance(prob, Problem):
            got = "None" if prob is None else f"a {type(prob).__name__}"
            raise ProblemInputError(f"{where}: build(comm, ...) returned {got}, not a Problem"
                                    + (" (a missing return?)" if prob is None else ""))
        # as run.json will hold them (lists, strings), so that a checkpoint's identity compares equal
        prob.args = {k: (str(v) if isinstance(v, Path) else list(v) if isinstance(v, tuple) else v)
                     for k, v in values.items()}
        prob.source, prob.source_sha256 = self.source, self.source_sha256
        return prob

    def units(self) -> dict[str, str]:
        return {p.name: p.unit for p in self.params}

    @property
    def summary(self) -> str:
        """The first line of ``doc``."""
        return (self.doc or self.name).strip().splitlines()[0]
