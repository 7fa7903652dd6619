"""Friction at the constrained vertices (Tresca or Coulomb), the run option ``friction``.

At each constrained vertex i the normal dof is the constrained component (the problem's
``constraint_component``: the obstacle's normal is that axis) and the tangential dofs are the
other components: one in 2-D, two in 3-D (then lam_T,i and d_i are 2-vectors and |.| their
Euclidean norm: the friction cone is a disc). Beside the normal multiplier lam_N,i >= 0 a
tangential one lam_T,i (the obstacle's tangential reaction, a nodal force like lam_N) satisfies

    Tresca:   |lam_T,i| <= s_i = s * m_i     (s a stress, m_i = the vertex's lumped boundary
                                              measure, as the contact stress is lam_N,i / m_i),
    Coulomb:  |lam_T,i| <= mu lam_N,i,

and opposes the slip d_i of the step: |lam_T,i| < bound => d_i = 0 (stick), d_i != 0 =>
lam_T,i = -bound d_i / |d_i| (slip; in 2-D -bound sign(d_i)). Tresca acts at every constrained vertex, in contact or
not (the classical Tresca problem, for a body in lasting contact); Coulomb's bound vanishes
off contact.

Which slip: d = X_t - U^n_t, the step's increment of the iterate the scheme constrains
(midpoint: X = U^{n+1/2}; backward Euler: X = U^{n+1}). Why: both schemes' energy balance
(the paper's proof of Theorem 2, with r = K X - b the obstacle's reaction) is

    E^{n+1} - E^n = r . (U^{n+1} - U^n)     (midpoint: exactly; backward Euler: minus its
                                             numerical dissipation),

and U^{n+1} - U^n = 2 (X - U^n) (midpoint) or X - U^n (backward Euler), so the tangential
part is 2 sum lam_T,i . d_i = -2 sum bound_i |d_i| <= 0 (midpoint, 2-D and 3-D): friction only removes
energy, and E + ``dissipated`` (the cumulative -lam_T . (U^{n+1} - U^n)_t) is conserved by
the midpoint scheme whenever the normal contact does no work (a body resting on the
obstacle). A slip measured from U^{n-1/2} instead (the previous constrained iterate) would
leave a term lam_T . (U^{n-1/2} - U^n) of either sign in the balance.

Between deformable bodies (``contact_pairs``, :mod:`sdm_dolfinx.method.body_rows`) the normal and
tangential "dofs" are rows: n . (X_i - sum_v xi_v X_v) and t . (X_i - sum_v xi_v X_v) for each tangent t of
the master's normal n (:func:`~sdm_dolfinx.solvers.friction_frames.frames_of`), rebuilt before every step
from the slave vertices' projections. The slip d = t . ((X - U^n)_i - sum_v xi_v (X - U^n)_v) is the relative
tangential motion, the multiplier acts equally and oppositely on the two bodies, and the energy argument
above holds with r = R^T lam (R the rows): the tangential part is again 2 sum lam_T,i . d_i <= 0.

The step problem is solved by :class:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton` (2-D)
or :class:`~sdm_dolfinx.solvers.friction_cone.FrictionalNewtonCone` (3-D) (Hüeber, Stadler,
Wohlmuth's primal-dual active set with stick and slip sets), with the step matrix factorised
once per run as without friction. In 3-D the step's ``tangential_force`` is |sum lam_T| and
``tangential_force_t`` its two components; ``Integrator.slip`` and ``Integrator.lam_t`` are
per-vertex sizes |U^{n+1} - U^n|_t and |lam_T| (``Integrator.slip_t`` and the solver's ``lam_t``
keep both components).
"""
from dataclasses import dataclass
from typing import Any, Optional

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.params import OptionError, Param, check_given
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.solvers.friction_cone import FrictionalNewtonCone
from sdm_dolfinx.solvers.friction_newton import FrictionalNewton
from sdm_dolfinx.solvers.friction_rows import rows_matrix

#: each friction law (the values of the run option ``friction``) and the options it declares
#: (``friction_options``)
LAW_OPTIONS: dict[str, tuple[Param, ...]] = {
    "none": (),
    "tresca": (Param("tresca_threshold", None, "Tresca's threshold, a stress in the problem's units", type=float,
                     low=0.0, expect="a number >= 0", metavar="S", required=True),),
    "coulomb": (Param("mu", None, "Coulomb's friction coefficient", type=float, low=0.0, expect="a number >= 0",
                      required=True),),
}
#: the values of the run option ``friction``
LAWS = tuple(LAW_OPTIONS)


def options_of(law: Optional[str]) -> tuple[Param, ...]:
    """The options the friction law ``law`` declares (None: ``"none"``)."""
    return LAW_OPTIONS[law or "none"]


@dataclass(frozen=True)
class Friction:
    """The friction law of a run: ``law`` (one of :data:`LAWS`), ``mu`` (Coulomb's coefficient)
    and ``threshold`` (Tresca's threshold, a stress: per unit measure of the boundary)."""
    law: str = "none"
    mu: Optional[float] = None
    threshold: Optional[float] = None

    @property
    def on(self):
        return self.law != "none"

    def describe(self):
        """For run.json."""
        if not self.on:
            return {"law": "none"}
        return {"law": self.law, **({"mu": self.mu} if self.law == "coulomb" else {"threshold": self.threshold}),
                "slip": "X_t - U^n_t (X: the constrained iterate)"}


def check(friction, mu, threshold):
    """Messages (a list, empty when good) for the run options ``friction``, ``mu``,
    ``tresca_threshold``: an unknown law, an option the law does not declare, a value its
    declaration refuses, a required one missing."""
    law = friction or "none"
    if law not in LAWS:
        return [f"unknown friction law {law!r}; choose one of {', '.join(LAWS)}"]
    return check_given(f"friction {law}", options_of(law), {"mu": mu, "tresca_threshold": threshold})


#: the step solver and linear strategies a frictional step can run with (its own semi-smooth
#: Newton method through one factorisation of the step matrix)
SOLVERS, LINEAR = ("ssn",), ("auto", "schur")


def check_solver(friction: Optional[str], vi_solver: Optional[str], linear: Optional[str]) -> list[str]:
    """Messages (a list) when the run options ask friction for a step solver it has not."""
    if (friction or "none") == "none" or (vi_solver in SOLVERS and linear in LINEAR):
        return []
    return [f"friction {friction} is solved by its own semi-smooth Newton method through one factorisation of the "
            f"step matrix (vi_solver {' or '.join(SOLVERS)}, linear {' or '.join(LINEAR)}), not vi_solver "
            f"{vi_solver} with linear {linear}"]


def make(friction=None, mu=None, threshold=None):
    """The :class:`Friction` of the run options (OptionError, a ValueError, one line, when they do
    not agree)."""
    errors = check(friction, mu, threshold)
    if errors:
        raise OptionError("; ".join(errors))
    law = friction or "none"
    return Friction(law, None if mu is None else float(mu), None if threshold is None else float(threshold))


def tangential_axes(problem: Any) -> tuple[int, ...]:
    """The components of u tangential to the obstacle (all but the constrained one): ``(0,)`` for a
    2-D problem bounded in y, ``(0, 1)`` for a 3-D one bounded in z; () for a scalar problem. A 3-D
    problem with ``obstacles`` or ``contact_pairs`` (whose tangent plane turns from node to node): ``(0, 1,
    2)``, the tangential vectors' Cartesian components."""
    shape = tuple(problem.shape)
    if not shape:
        return ()
    if shape[0] == 3 and (getattr(problem, "obstacles", None) or getattr(problem, "contact_pairs", None)):
        return (0, 1, 2)
    return tuple(c for c in range(shape[0]) if c != (problem.constraint_component or 0))


def contact_dofs(discretisation, friction):
    """(tangential dofs paired with ``discretisation.cdofs``: m in 2-D, m x 2 in 3-D; the Tresca
    thresholds per vertex or None) for ``friction``; ValueError (one line) for a problem friction
    does not apply to."""
    d = discretisation
    p = d.problem
    shape = tuple(p.shape)
    if not shape:
        raise ValueError(f"friction {friction.law}: problem {p.name!r} has a scalar unknown (no tangential "
                         f"direction)")
    if shape[0] not in (2, 3):
        raise ValueError(f"friction {friction.law}: problems with 2 or 3 components only (problem {p.name!r} has "
                         f"{shape[0]} components)")
    comp = p.constraint_component
    if shape[0] == 2:
        tdofs = (d.cdofs - comp + (1 - comp)).astype(np.int32)
    else:                               # 3-D: the two other components, in increasing order (m x 2)
        tdofs = np.column_stack([d.cdofs - comp + c for c in range(3) if c != comp]).astype(np.int32)
    thresholds = friction.threshold * d.cmeasure if friction.law == "tresca" else None
    return tdofs, thresholds


def _carried(integ):
    """The moving obstacles' own tangential displacement over the step at the contact nodes, in their
    frames (``ObstacleRows.carried``), or None when no obstacle moves."""
    rows = integ.discretisation.obstacle_rows
    return integ.solver.frame_tangential(rows.carried) if rows is not None and rows.moves else None


def slip_reference(integ, u):
    """The step's reference of the slip, ``xref_t`` of the frictional solver: the tangential components
    of U^n = ``u``; against a moving obstacle plus its own tangential displacement at the scheme's
    constraint time (the part ``bound_weight`` of the step's, as its rows take the obstacle: the midpoint's
    half), so that the slip is measured against the obstacle's surface, not the fixed frame."""
    ref = integ.solver.tangential(u)
    carried = _carried(integ)
    return ref if carried is None else ref + integ.time_scheme.bound_weight * carried


def step_info(integ, info, u, un):
    """The frictional step's tangential force, slip (U^{n+1} - U^n at the tangential dofs, kept as
    ``integ.slip_t``; against a moving obstacle less the obstacle's own tangential displacement: the
    relative slip) and friction work lam_T . slip (<= 0: what friction dissipates), reduced over the
    ranks, into ``info`` (3-D: the force's size and its components ``tangential_force_t``; ``integ.slip``
    per vertex its size); against a moving obstacle also ``obstacle_friction_work``, the work of the
    friction force on the obstacle's motion, lam_T . (its tangential displacement). ``integ`` is the
    run's Integrator."""
    comm = integ.discretisation.comm
    integ.slip_t = integ.solver.tangential(u) - integ.solver.tangential(un)
    lam_t = integ.solver.lam_t
    carried = _carried(integ)
    if carried is not None:
        integ.slip_t = integ.slip_t - carried
        info["obstacle_friction_work"] = comm.allreduce(float(np.sum(lam_t * carried)), op=MPI.SUM)
    if lam_t.ndim == 1:
        integ.slip = integ.slip_t
        force, work = comm.allreduce(np.array([np.sum(lam_t), np.dot(lam_t, integ.slip)]), op=MPI.SUM)
        info.update(tangential_force=float(force), friction_work=float(work))
        return
    # 3-D: the force's tangential components (obstacles: Cartesian, the frames turn from node to node);
    # slip (per vertex) is |(U^{n+1} - U^n)_t|
    work = np.sum(lam_t * integ.slip_t)
    integ.slip_t = integ.solver.cartesian(integ.slip_t)
    integ.slip = np.linalg.norm(integ.slip_t, axis=1)
    force = integ.solver.cartesian(lam_t)
    k = force.shape[1]
    total = comm.allreduce(np.r_[force.sum(axis=0), work], op=MPI.SUM)
    size = np.hypot(total[0], total[1]) if k == 2 else np.linalg.norm(total[:k])
    info.update(tangential_force=float(size), tangential_force_t=total[:k].tolist(),
                friction_work=float(total[k]))


def make_solver(integ, options):
    """The frictional step solver of the Integrator ``integ`` (2-D: :class:`FrictionalNewton`, 3-D: m x 2
    tangential dofs, :class:`FrictionalNewtonCone`); sets ``integ.tdofs``, ``slip`` and ``slip_t``."""
    return solver_factory(integ, options)(integ.K, not integ.block, integ.factor_matrix, None)


def solver_factory(integ, options):
    """``factory(K, symmetric_positive, factor_matrix, prefix)``: the frictional step solver of the
    Integrator ``integ`` with the step matrix K (a hyperelastic run makes one per tangent); sets
    ``integ.tdofs``, ``slip`` and ``slip_t``."""
    d, f = integ.discretisation, integ.friction
    try:
        integ.tdofs, thresholds = contact_dofs(d, f)
    except ValueError as e:
        raise DiscretisationError(str(e)) from None
    ndofs, lb, rows = d.cdofs, d.lb, d.obstacle_rows
    if rows is not None:            # obstacles: each node's Cartesian dofs, its frame given every step
        rows.require_free(f"friction {f.law} against obstacles")
        ndofs, lb = rows.dofs[:, 0], np.zeros(len(rows.dofs))
        integ.tdofs = rows.dofs[:, 1] if rows.gdim == 2 else np.ascontiguousarray(rows.dofs[:, 1:])
    weighted = getattr(d, "weighted_rows", None)
    if weighted is not None:        # the weighted gap: its rows, and the same weights on the tangential components
        comp = d.problem.constraint_component or 0
        weighted = rows_matrix(weighted.G, comp, tangential_axes(d.problem), d.comm)
        lb = d.weighted_rows.g
    bodies = getattr(d, "body_rows", None)
    if bodies is not None:          # between bodies: the rows along the master's normal and tangents, every step
        integ.row_options = {"tangential": True}
    cls = FrictionalNewtonCone if integ.tdofs.ndim == 2 else FrictionalNewton
    integ.slip = np.zeros(len(integ.tdofs))
    cartesian = (rows is not None and rows.gdim == 3) or (bodies is not None and bodies.gdim == 3)
    integ.slip_t = np.zeros((len(integ.tdofs), 3) if cartesian else integ.tdofs.shape)
    tdofs = integ.tdofs

    def factory(K, symmetric_positive, factor_matrix, prefix):
        return cls(K, ndofs, tdofs, lb, law=f.law, mu=f.mu, threshold=thresholds,
                   symmetric_positive=symmetric_positive, options=options, factor_matrix=factor_matrix,
                   frames=rows is not None, rows=weighted, surface=None if bodies is None else bodies.read,
                   prefix=prefix)
    return factory
