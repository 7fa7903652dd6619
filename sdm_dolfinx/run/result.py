"""What a run returns (:class:`Result`) and the time series it records (:class:`TimeSeries`)."""
from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Optional, Protocol, Union

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.contact import friction as _friction
from sdm_dolfinx.errors import StepError
from sdm_dolfinx.method import gaps, moving_bound
from sdm_dolfinx.run import body_columns
from sdm_dolfinx.run.boundary_sink import BOUNDARY_GAP, BoundarySink
# public here too (tests and users import them from this module)
from sdm_dolfinx.run.boundary_sink import BOUNDARY_GAP_FLOOR as BOUNDARY_GAP_FLOOR  # noqa: F401
from sdm_dolfinx.run.boundary_sink import BOUNDARY_GAP_TOL as BOUNDARY_GAP_TOL  # noqa: F401
from sdm_dolfinx.run.boundary_sink import BOUNDARY_SINK_RTOL as BOUNDARY_SINK_RTOL  # noqa: F401
from sdm_dolfinx.run.boundary_sink import BoundaryGapWarning as BoundaryGapWarning  # noqa: F401
from sdm_dolfinx.run.linear_range import LinearRange

if TYPE_CHECKING:
    from dolfinx import fem
    from petsc4py import PETSc

    from sdm_dolfinx.method.discretisation import Discretisation
    from sdm_dolfinx.problems import Problem
    from sdm_dolfinx.run.probes import ConstraintProbe, PointProbe

#: the columns of every run's time series; a Problem adds its ``extra_columns``
BASE_COLUMNS = ("step", "t", "energy", "kinetic", "potential", "u_probe", "lambda_probe", "n_active",
                "newton_its")
#: the columns of a run with friction (docs/outputs.md): the step's sum of the tangential
#: multipliers, the slip U^{n+1} - U^n of the probe's constrained vertex along the tangent, the
#: cumulative friction dissipation -sum_steps lam_T . (U^{n+1} - U^n)_t (>= 0), the numbers of
#: sticking and slipping vertices (the step solver's sets); in 3-D the first two are written per
#: tangential axis, signed (:func:`friction_columns`)
FRICTION_COLUMNS = ("tangential_force", "slip_probe", "dissipated", "n_stick", "n_slip")
#: the columns of a run whose obstacle moves (``Problem.moving_bound``, docs/outputs.md): the
#: cumulative work of the contact force on the obstacle's motion sum_steps sum_i lam_i (g_i(t_{n+1}) -
#: g_i(t_n)) (E - obstacle_work is conserved by the midpoint scheme in sustained contact:
#: :mod:`sdm_dolfinx.schemes.midpoint`), and the bound g(t) at the probe's constrained vertex (the
#: obstacle's position there, in displacement: the vertex a touches it when u_c(a) = obstacle_probe)
OBSTACLE_COLUMNS = ("obstacle_work", "obstacle_probe")


def friction_columns(problem: Problem) -> tuple[str, ...]:
    """The friction columns of ``problem``'s time series: :data:`FRICTION_COLUMNS` in 2-D (the one
    tangential component, signed); in 3-D ``tangential_force`` and ``slip_probe`` become one signed
    column per tangential axis, e.g. ``tangential_force_x``, ``tangential_force_y`` for a body
    bounded in z (a single column would be the vector's size, unsigned)."""
    axes = _friction.tangential_axes(problem)
    if len(axes) < 2:
        return FRICTION_COLUMNS
    names = ["xyz"[c] for c in axes]
    return (*(f"tangential_force_{a}" for a in names), *(f"slip_probe_{a}" for a in names), *FRICTION_COLUMNS[2:])


#: the column of a run whose Problem declares Dirichlet parts: the cumulative work of their reactions on
#: the prescribed motion, sum over the steps of R . (U^{n+1} - U^n) at the parts' dofs (the midpoint scheme
#: conserves energy - dirichlet_work without impact); the reactions are ``reaction_<part>_<x|y|z>``
DIRICHLET_WORK = "dirichlet_work"


def dirichlet_columns(problem: Problem) -> tuple[str, ...]:
    """The reaction columns of ``problem``'s Dirichlet parts (per part and prescribed component) and
    :data:`DIRICHLET_WORK`, or () without parts."""
    parts = tuple(problem.dirichlet_parts)
    if not parts:
        return ()
    shape = tuple(problem.shape)
    return (*(c for part in parts for c in part.columns(shape)), DIRICHLET_WORK)


#: the columns of a hyperelastic run (run option ``material``, docs/finite_strain.md): the step's Newton
#: iterations on its nonlinear VI and the tangents factorised in it (``newton_its`` counts the semi-smooth
#: Newton's active-set iterations over all of them), the Newton steps halved (``backtracks``) and the
#: iterations redone with the step matrix at rest when a tangent's LCP cycled (``fallbacks``), and the
#: angular momentum sum_ab M_ab x_a x Vbar_b about the origin (x = X + U; 3-D: one column per axis)
FINITE_STRAIN_COLUMNS = ("nonlinear_its", "tangents", "backtracks", "fallbacks")


def finite_strain_columns(gdim: int) -> tuple[str, ...]:
    """The columns of a hyperelastic run in ``gdim`` dimensions (:data:`FINITE_STRAIN_COLUMNS`)."""
    angular = ("angular_momentum",) if gdim == 2 else tuple(f"angular_momentum_{a}" for a in "xyz")
    return (*FINITE_STRAIN_COLUMNS, *angular)


#: the column of a run whose contact is not exact (penalty, Nitsche): the energy stored in the
#: contact term at U^{n+1} (``Integrator.contact_energy``); ``energy`` includes it
CONTACT_ENERGY = "contact_energy"

#: one row of the time series: column -> value (and ``linear_its_total``)
Row = dict[str, float]
#: ``simulate``'s ``on_step(step, row)``, called after every step; a true return requests a stop
OnStep = Callable[[int, Row], object]


#: |J^0| below this times the largest energy in play is round-off of it (:func:`energy_scale`)
ENERGY_SCALE_RTOL = 1e-12


def energy_scale(series: Mapping[str, Any]) -> float:
    """The scale of a time series' energy ``J``: |J^0|, or, when that is 0 or below
    :data:`ENERGY_SCALE_RTOL` times the largest energy in play (max over the steps of |J|, the
    kinetic energy, |potential|, the contact energy), that largest energy: a body starting at
    rest has J^0 = 0, and its J stays at round-off while its kinetic energy grows."""
    E = np.asarray(series["energy"], dtype=float)
    if not E.size:
        return 0.0
    play = max(float(np.max(np.abs(np.asarray(series[c], dtype=float))))
               for c in ("energy", "kinetic", "potential", CONTACT_ENERGY) if c in series)
    return abs(float(E[0])) if abs(float(E[0])) > ENERGY_SCALE_RTOL * play else play


def num_steps(T: float, dt: float) -> int:
    """Number of steps of length dt in [0, T] (T rounded to a multiple of dt)."""
    return int(np.floor(T / dt + 1e-9))


class Formulation(Protocol):
    """What the time series reads of the run's formulation (the Integrator is one): the discrete
    energy and momentum of the state, collective, changing nothing."""

    def energies(self, U: PETSc.Vec, V: PETSc.Vec, time: Optional[float] = None) -> tuple[float, float]:
        """(kinetic, potential) of the state, the load taken at ``time``."""

    def contact_energy(self, U: PETSc.Vec, time: Optional[float] = None) -> float:
        """The energy stored in the contact treatment at U at ``time`` (0.0 for the exact contact)."""

    def momentum(self, V: PETSc.Vec, component: int) -> float:
        """The discrete momentum along ``component``."""

    def load(self, t: Optional[float] = None) -> PETSc.Vec:
        """The load vector L at time ``t``."""

    def angular_momentum(self, U: PETSc.Vec, V: PETSc.Vec) -> Union[float, list[float]]:
        """The angular momentum of the state about the origin (2-D: a float; 3-D: three)."""


class TimeSeries:
    """The scalar history of a run: one row per step (row 0 = the initial state).

    Every value is reduced over the ranks (identical on every rank).

    Args:
        formulation: the energies and momentum of the state (:class:`Formulation`).
        discretisation: the run's Discretisation (the gaps, the constrained boundary).
        friction: the run has friction (the :data:`FRICTION_COLUMNS`).
        contact_energy: the contact stores energy (a treatment other than ``exact``: the
            :data:`CONTACT_ENERGY` column).
    """

    def __init__(self, formulation: Formulation, discretisation: Discretisation, problem: Problem, probe: PointProbe,
                 cprobe: ConstraintProbe, nsteps: int, friction: bool = False, contact_energy: bool = False) -> None:
        self.formulation, self.problem, self.probe, self.cprobe = formulation, problem, probe, cprobe
        self.discretisation = d = discretisation
        boundary = (BOUNDARY_GAP,) if d.num_boundary_dofs else ()
        friction_cols = friction_columns(problem) if friction else ()
        contact = (CONTACT_ENERGY,) if contact_energy else ()
        dirichlet = dirichlet_columns(problem)
        self.reaction_columns = dirichlet[:-1]
        obstacle: tuple[str, ...] = OBSTACLE_COLUMNS if moving_bound.moves(d) else ()
        if d.obstacle_rows is not None and d.obstacle_rows.moves:      # moving obstacles: their work only
            obstacle = OBSTACLE_COLUMNS[:1]
        per_body = body_columns.columns(problem)
        finite = (finite_strain_columns(problem.mesh.geometry.dim) if getattr(formulation, "finite_strain", None)
                  else ())
        self.columns: tuple[str, ...] = (BASE_COLUMNS + contact + tuple(problem.extra_columns) + friction_cols
                                         + boundary + dirichlet + obstacle + per_body + finite)
        #: the per-body and per-pair columns (:mod:`.body_columns`), or None
        self.body_columns = body_columns.BodyColumns(d) if per_body else None
        self.data = {c: np.zeros(nsteps + 1) for c in self.columns}
        self.comm = problem.mesh.comm
        #: the deepest sink of the constrained boundary (:mod:`.boundary_sink`), or None without one
        self.boundary_sink = BoundarySink(d) if boundary else None
        #: the largest cell rotation and strain of the run (a vector displacement in 2-D or 3-D), or None
        self.linear_range = (LinearRange(d.W) if LinearRange.applies(tuple(problem.shape), problem.mesh.geometry.dim)
                             and not finite else None)

    def record(self, n: int, t: float, U: PETSc.Vec, V: PETSc.Vec, lam: npt.NDArray[np.float64], its: int,
               n_active: int, step: Optional[Mapping[str, Any]] = None, *, linear_its_total: int,
               slip: Optional[npt.NDArray[np.float64]] = None) -> Row:
        """Compute row ``n`` (time ``t``) from the state and the step solver's ``step`` info (None
        for row 0); returns it as a dict (with ``linear_its_total``, the cumulative linear
        iterations, for callbacks). ``slip``: the step's slip at the owned constrained vertices
        (friction)."""
        f, comm = self.formulation, self.comm
        kin, pot = f.energies(U, V, t)
        stored = f.contact_energy(U, t) if CONTACT_ENERGY in self.columns else 0.0
        row = {"step": n, "t": t, "energy": kin + pot + stored, "kinetic": kin, "potential": pot,
               "u_probe": self.probe(U), "lambda_probe": self.cprobe(lam), "n_active": n_active,
               "newton_its": its}
        if CONTACT_ENERGY in self.columns:
            row[CONTACT_ENERGY] = stored
        if "contact_force" in self.columns:
            row["contact_force"] = comm.allreduce(float(np.sum(lam)), op=MPI.SUM)
        if "momentum_y" in self.columns:
            row["momentum_y"] = f.momentum(V, self.problem.momentum_component)
        if "momentum_x" in self.columns:
            row["momentum_x"] = f.momentum(V, 0)
        if "dissipated" in self.columns:
            self._friction_row(row, n, step or {}, slip)
        if DIRICHLET_WORK in self.columns:      # the step's reactions (0 in row 0) and the cumulative work
            info = step or {}
            row.update(zip(self.reaction_columns, info.get("reactions", [0.0] * len(self.reaction_columns))))
            before = self.data[DIRICHLET_WORK][n - 1] if n > 0 else 0.0    # a restart's: read back from the CSV
            row[DIRICHLET_WORK] = before + info.get("dirichlet_work", 0.0)
        if "elastic" in self.columns:            # 1/2 U^T A U = potential + U^T L
            row["elastic"] = pot + U.dot(f.load(t))
        if "obstacle_work" in self.columns:      # the discretisation's lb is the bound at the state's time
            before = self.data["obstacle_work"][n - 1] if n > 0 else 0.0
            row["obstacle_work"] = before + (step or {}).get("obstacle_work", 0.0)
        if "obstacle_probe" in self.columns:
            row["obstacle_probe"] = self.cprobe.at(self.discretisation.lb)
        if self.boundary_sink is not None:          # the column BOUNDARY_GAP
            row[BOUNDARY_GAP] = gaps.boundary_gap(self.discretisation, U.array_r, t)
            self.boundary_sink.track(n, t, U, row[BOUNDARY_GAP])
        if self.linear_range is not None:
            self.linear_range.watch(n, t, U)
        if self.body_columns is not None:
            row.update(self.body_columns.values(U, V, lam if step is not None else np.zeros(0)))
        if "nonlinear_its" in self.columns:
            self._finite_strain_row(row, U, V, step or {})
        row["linear_its_total"] = linear_its_total
        if not np.isfinite(row["energy"]):
            raise StepError(f"step {n} (t = {t:.6g}): the energy is not finite ({row['energy']})")
        for c in self.columns:
            self.data[c][n] = row[c]
        return row

    def _finite_strain_row(self, row: Row, U: PETSc.Vec, V: PETSc.Vec, step: Mapping[str, Any]) -> None:
        """The :func:`finite_strain_columns` of a row (the iteration counts 0 in row 0)."""
        row.update(nonlinear_its=step.get("nonlinear_its", 0), tangents=step.get("tangents", 0),
                   backtracks=step.get("cuts", 0), fallbacks=step.get("fallbacks", 0))
        angular = self.formulation.angular_momentum(U, V)
        if isinstance(angular, float):
            row["angular_momentum"] = angular
        else:
            row.update(zip((f"angular_momentum_{a}" for a in "xyz"), angular))

    def _friction_row(self, row: Row, n: int, step: Mapping[str, Any],
                      slip: Optional[npt.NDArray[np.float64]]) -> None:
        """The friction columns of row ``n`` (0 in row 0; ``dissipated`` accumulates); ``slip``: the
        step's slip at the owned constrained vertices (m, or m x 2 in 3-D)."""
        before = self.data["dissipated"][n - 1] if n > 0 else 0.0
        row.update(dissipated=before - step.get("friction_work", 0.0),
                   n_stick=step.get("n_stick", 0), n_slip=step.get("n_slip", 0))
        if "tangential_force" in self.columns:
            row.update(tangential_force=step.get("tangential_force", 0.0),
                       slip_probe=self.cprobe.at(slip) if step and slip is not None else 0.0)
            return
        forces = [c for c in self.columns if c.startswith("tangential_force_")]
        slips = [c for c in self.columns if c.startswith("slip_probe_")]
        force = step.get("tangential_force_t", [0.0] * len(forces))
        at = self.cprobe.at_components(slip, len(slips)) if step and slip is not None else [0.0] * len(slips)
        row.update(zip(forces, map(float, force)))
        row.update(zip(slips, map(float, at)))

    def warn_end(self) -> None:
        """The run's end-of-run warnings (collective): the boundary's sink (:mod:`.boundary_sink`) and a
        rotation or strain beyond the linear model's range (:mod:`.linear_range`)."""
        if self.boundary_sink is not None:
            self.boundary_sink.warn()
        if self.linear_range is not None:
            self.linear_range.warn()

    def summary(self, first: int = 0) -> dict[str, float]:
        """What ``run.json`` gets from the time series of steps ``first``+1.. (the minimum of
        :data:`BOUNDARY_GAP` over the run, when the column exists) and the largest cell rotation and
        strain of the steps recorded (a vector problem in 2-D or 3-D: :mod:`.linear_range`)."""
        out = {}
        if BOUNDARY_GAP in self.columns:
            out["min_gap_boundary"] = float(np.min(self.data[BOUNDARY_GAP][first + 1:], initial=np.inf))
        if self.linear_range is not None:
            out.update(zip(("max_cell_rotation", "max_cell_strain"), map(float, self.linear_range.largest)))
        return out

    def load_rows(self, lines: Iterable[str]) -> None:
        """Fill rows from CSV lines (``step,...`` in the column order; a restart's history)."""
        for line in lines:
            vals = line.split(",")
            for c, v in zip(self.columns, vals):
                self.data[c][int(vals[0])] = float(v)


@dataclass
class Result:
    """What a run produced.

    Attributes:
        timeseries: column name -> numpy array (one entry per step, entry 0 = initial state).
        info: what ``run.json`` holds (parameters, dofs, versions, wall time, ...).
        gap_imposed: per step, min over constraints of (constrained iterate - bound).
        gap_end: per step, min over constraints of (U^{n+1} - bound).
            (``timeseries["gap_min_boundary"]`` has the same at every dof of the constrained
            boundary, P2 mid-edge nodes included: row n + 1 for step n.)
        U, V: final state vectors (PETSc, owned entries); V is Vbar in W, or V in H for the
            consistent block variant.
        discretisation: the :class:`sdm_dolfinx.method.discretisation.Discretisation`.
    """
    timeseries: dict[str, npt.NDArray[np.float64]]
    info: dict[str, Any]
    gap_imposed: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    gap_end: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    U: Optional[PETSc.Vec] = None
    V: Optional[PETSc.Vec] = None
    discretisation: Optional[Discretisation] = None

    def __post_init__(self) -> None:
        """The final fields as dolfinx Functions, made now (collective: a Result is made on every
        rank), so that :meth:`displacement`, :meth:`velocity` and :meth:`vbar` are not: each
        returns a copy, which any one rank may ask for (creating a Function, or updating its
        ghosts, is collective in dolfinx: called on rank 0 only, they hung)."""
        self._fields: dict[str, fem.Function] = {}
        d = self.discretisation
        if d is None or self.U is None or self.V is None:
            return
        self._fields["displacement"] = self._function(d.W, self.U, "displacement")
        if d.mass == "consistent":
            self._fields["velocity"] = self._function(d.H, self.V, "velocity")
        elif d.H is None:
            self._fields["velocity"] = self._function(d.W, self.V, "velocity")
        else:
            v = d.physical_velocity(self.V, d.B.createVecLeft())
            self._fields["velocity"] = self._function(d.H, v, "velocity")
            v.destroy()
        if d.mass != "consistent":
            self._fields["Vbar_W"] = self._function(d.W, self.V, "Vbar_W")

    def displacement(self) -> fem.Function:
        """The final displacement U as a dolfinx Function of W^h (for plotting, probing,
        post-processing): a new copy at each call, on any rank (not collective)."""
        return self._copy("displacement")

    def velocity(self) -> fem.Function:
        """The final physical velocity as a dolfinx Function: v_h = C^-1 B Vbar in H^h (C as the
        run treats it: diagonal for P0, lumped for P1), V in H^h for the consistent block
        variant, Vbar in W^h for the standard method (H^h = W^h). The XDMF's ``velocity``. A
        new copy at each call, on any rank (not collective)."""
        return self._copy("velocity")

    def vbar(self) -> fem.Function:
        """The final Vbar in W^h, the scheme's M-formulation vector (the XDMF's ``Vbar_W``): only
        M Vbar is determined by the scheme; with a singular M (dim H^h < dim W^h) Vbar also has a
        component in Ker(M) that carries no kinetic energy (see docs/outputs.md). ValueError for
        the consistent block variant, which has no Vbar. A new copy at each call, on any rank."""
        if self.discretisation is not None and self.discretisation.mass == "consistent":
            raise ValueError("the (U, V) block system (--mass consistent) has no Vbar: its velocity is in H^h")
        return self._copy("Vbar_W")

    def _copy(self, name: str) -> fem.Function:
        if name not in self._fields:
            raise ValueError("this Result holds no final state (U, V and the discretisation)")
        f: fem.Function = self._fields[name].copy()      # rank-local: the copy shares the space's ghost layout
        f.name = name
        return f

    def max_energy_deviation(self) -> float:
        """max_n |J^n - J^0| / scale of the discrete energy (Theorem 2: 0 for the midpoint scheme
        without impact). The scale is |J^0|, or, when J^0 is 0 or round-off of the energies in play
        (a body starting at rest: J stays 0 while gravity turns potential into kinetic energy), the
        largest of those: :func:`energy_scale`. 0.0 when nothing moves (every energy 0)."""
        E = np.asarray(self.timeseries["energy"])
        if not E.size:
            return float("nan")
        deviation = float(np.max(np.abs(E - E[0])))
        scale = energy_scale(self.timeseries)
        if scale == 0.0:
            return 0.0 if deviation == 0.0 else float("inf")
        return deviation / scale

    @staticmethod
    def _function(space: fem.FunctionSpace, vec: PETSc.Vec, name: str) -> fem.Function:
        from dolfinx import fem
        f = fem.Function(space, name=name)
        f.x.array[:len(vec.array)] = vec.array
        f.x.scatter_forward()
        return f
