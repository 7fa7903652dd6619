"""The equilibrium start of any Problem: ``u0 = "equilibrium"``, the static Signorini solution in W^h.

The static problem of the run's own discretisation, from its own matrices (so in its W^h
element, with its constraint kind, quadrature and Dirichlet data): find U with

    A U = L + r,   U_c >= g and r_c >= 0 and r_c (U_c - g) = 0 at the constrained dofs,
    U = u_D at the Dirichlet dofs,   r = 0 elsewhere,

L the load at t = 0 (a time-dependent load: its value at t = 0). It is solved by an active-set
loop of linear solves (MUMPS on A with the active and Dirichlet dofs eliminated): start with
the constrained dofs touching in the reference configuration (the lowest ones if none does),
release an active dof whose reaction pulls (r_c < 0), add an inactive one that penetrates,
until neither happens. Started there with zero velocity a run stays there: with
U^n = U_s the midpoint scheme's step (and backward Euler's) is solved by U^{n+1} = U_s with the
multipliers r_c, so the contact force is the load's normal part at every step.

With friction (the run's ``friction``, Coulomb or Tresca) the static problem is the first load
step from the unstressed body: an active node sticks (U_t = 0) while its tangential reaction lies
in the cone (Coulomb |r_t| <= mu r_c, Tresca |r_t| <= s m_i), else it slips with the reaction
-bound U_t / |U_t| on the cone's edge; the stick and slip sets, the slip directions (3-D: a Newton
step on -bound U_t / |U_t|) and Coulomb's bound mu r_c are updated in the same loop until they
are unchanged (to the relative tolerance :data:`RTOL`). Started there, the run's first slip
d = X_t - U_t is 0 with |lam_T| <= bound: the body stays at rest (a sticking block on an incline
whose contact edge slips).

**Against obstacles** (``Problem.obstacles``) each constrained node i is held by its row
n_i . U_i >= -phi(a_i) linearised at the reference configuration (n_i the nearest obstacle's normal at
the node a_i, phi its signed distance there, at t = 0): the problem is solved in each node's frame,
U_i = Q_i^T Y_i with Q_i orthonormal and its row ``constraint_component`` the normal (the others the
tangents of :func:`~sdm_dolfinx.solvers.friction_frames.frames_of`), so that the row is the bound
Y_c >= -phi(a_i) of one unknown and everything above applies to A_Y = T^T A T, L_Y = T^T L (T the
rotation, the identity off the constrained nodes; friction: the tangential unknowns of the frame).
The run's first step linearises its rows at U_s instead: they differ by O(|U_s,t|^2 / R) on an
obstacle of curvature radius R (0 on a plane: there the run stays at U_s to round-off).

**With the weighted gap** (``constrain="weighted"``) a row reads several nodes: the active rows (and with
friction their sticking tangential rows) are held by multipliers instead of eliminated dofs
(:mod:`.static_rows`, the same loop).

A rigid motion that A does not resist (the translations and rotations for a vector u, the
constant for a scalar u, where ``A r = 0``) and that neither the active contact, the sticking
dofs nor the Dirichlet data fix is a free motion of the body: the static problem then has a
solution only if the load does no work along it (``r . L = 0``); it is refused in one line
otherwise (a frictionless body on an incline, a body the load lifts off the obstacle, a disc
touching at one vertex under a load with a moment about it), and when it holds the solution is
taken with no rigid displacement along the free motions (``R^T M U = 0``: the centre of mass
does not move along them). A matrix singular otherwise (a mechanism that is no rigid motion)
is refused too.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.method import static_rows
from sdm_dolfinx.method.static_frame import ObstacleFrame
from sdm_dolfinx.method.static_parts import (MAX_ITER, RESIDUAL_TOL, RTOL, StaticStartError,  # noqa: F401 (public)
                                             free_or_refuse, kernel_basis, load_at_zero, lu_solve,
                                             no_rigid_displacement, stick_or_slip)
from sdm_dolfinx.problems.base import EQUILIBRIUM as EQUILIBRIUM  # noqa: F401  (the value of u0 asking for it)
from sdm_dolfinx.problems.base import label


def initial_displacement(d, u0, friction=None, contact="exact"):
    """Set the Function ``u0`` of W^h to the Problem's u0 for the Discretisation ``d``: interpolated (a
    callable, a Function; a built-in equilibrium start's ``for_constraint(kind)`` for the run's kind), or
    ``"equilibrium"``: :func:`static_displacement` with the run's ``friction`` and ``contact``. Collective."""
    p = d.problem
    start = p.u0
    if not isinstance(start, str):          # validated: a string is EQUILIBRIUM
        start = getattr(start, "for_constraint", lambda kind: start)(d.constrain)
    if not isinstance(start, str):          # a built-in start's own solution, or the run's (EQUILIBRIUM)
        u0.interpolate(start)
        return
    if getattr(d, "body_rows", None) is not None:
        raise DiscretisationError(f"problem {p.name!r}: the equilibrium start is not built for contact pairs yet: "
                                  f"give u0 as x -> values")
    Us = static_displacement(d, friction, contact)
    u0.x.array[:len(Us.array_r)] = Us.array_r          # the owned entries: the same layout
    u0.x.scatter_forward()
    Us.destroy()


def _solve_fixed(A, L, dofs, values, comm, blocks=()):
    """(A + D) u = L with u = ``values`` at the owned local indices ``dofs``: symmetric elimination, MUMPS;
    D: the ``blocks`` [(owned local indices, square matrix)] added to A. Returns (u, KSP converged reason)."""
    r0 = A.getOwnershipRange()[0]
    rows = (r0 + np.asarray(dofs, dtype=np.int64)).astype(PETSc.IntType)
    x0, b, u = A.createVecRight(), L.copy(), A.createVecRight()
    x0.setValues(rows, np.asarray(values, dtype=PETSc.ScalarType))
    x0.assemble()
    K = A.copy()
    for idx, block in blocks:
        g = (r0 + np.asarray(idx, dtype=np.int64)).astype(PETSc.IntType)
        K.setValues(g, g, np.asarray(block, dtype=PETSc.ScalarType), addv=PETSc.InsertMode.ADD_VALUES)
    K.assemble()
    K.zeroRowsColumns(rows, 1.0, x0, b)
    reason = lu_solve(K, b, u)
    K.destroy(), b.destroy(), x0.destroy()
    return u, reason


def _tangential(d):
    """The tangential dofs paired with ``d.cdofs`` (the pairing of :func:`sdm_dolfinx.contact.friction.
    contact_dofs`: the other components of the same node), m x (gdim - 1)."""
    comp, n = d.problem.constraint_component, d.problem.shape[0]
    return np.column_stack([d.cdofs - comp + c for c in range(n) if c != comp]).astype(np.int64)


def static_displacement(d, friction=None, contact="exact"):
    """The static displacement U_s (a PETSc vector of W^h) of the Discretisation ``d`` (the module's
    docstring); ``friction`` (an object with ``law``, ``mu``, ``threshold``, or None) holds the active
    dofs tangentially (stick, or slip at the cone's edge). Collective.

    Raises:
        StaticStartError: a contact treatment other than "exact" (its equilibrium penetrates), a free
            rigid motion along which the load works (a body that would lift off, slide or slip as a
            whole), a matrix singular otherwise, no active set in :data:`MAX_ITER` changes.
    """
    who = f"{label(d.problem)}: u0 = 'equilibrium'"
    if contact != "exact":
        raise StaticStartError(f"{who} is the exact Signorini equilibrium, and contact {contact!r} penetrates the "
                               f"obstacle at rest: start from a u0 of your own (or contact 'exact')")
    if getattr(d, "weighted_rows", None) is not None:
        return static_rows.static_displacement(d, who, friction)
    frame = ObstacleFrame(d) if d.obstacle_rows is not None else None
    try:
        return _static(d, friction, who, frame)
    finally:
        if frame is not None:
            frame.destroy()


def _static(d, friction, who, frame):  # long: the active-set loop of static_displacement, as one piece
    """:func:`static_displacement`'s loop (``frame``: against obstacles, the nodes' frames, or None)."""
    p, comm = d.problem, d.comm
    law = getattr(friction, "law", "none") if friction is not None else "none"
    L = load_at_zero(d)
    A, lb, mass_mult = (d.A, d.lb, d.mass_mult) if frame is None else frame.start(L)   # obstacles: framed
    nloc = d.A.getLocalSize()[0]
    load = max(comm.allreduce(float(np.max(np.abs(L.array), initial=0.0)), op=MPI.MAX), np.finfo(float).tiny)
    x = p.mesh.geometry.x
    size = max(comm.allreduce(float(np.ptp(x, axis=0).max()) if len(x) else 0.0, op=MPI.MAX), 1.0)
    R, names = kernel_basis(d, nloc, frame)
    tdofs = _tangential(d) if law != "none" else np.zeros((len(d.cdofs), 0), dtype=np.int64)
    low = comm.allreduce(float(np.min(-lb, initial=np.inf)), op=MPI.MIN)      # -lb: the gap at U = 0
    active = -lb <= (max(low, 0.0) + RTOL * size)
    m, nt = tdofs.shape
    stick = np.ones(m, dtype=bool)                  # with friction: an active dof sticks, or slips along sdir
    sdir, bound, ulen = np.zeros((m, nt)), np.zeros(m), np.zeros(m)
    r = d.A.createVecLeft()
    for _ in range(MAX_ITER):
        slip = active & ~stick
        stuck = tdofs[active & stick].reshape(-1)
        dofs = np.concatenate([d.ddofs, d.cdofs[active], stuck]).astype(np.int64)
        values = np.concatenate([d.g.x.array[d.ddofs], lb[active], np.zeros(len(stuck))])
        b = L.copy()                                # the load, and the friction force -bound s where it slips
        if slip.any():
            b.array[tdofs[slip].reshape(-1)] -= (bound[slip, None] * sdir[slip]).reshape(-1)
        fixed = np.zeros(nloc, dtype=bool)
        fixed[dofs] = True
        counted = f"{d.num_constraints} constrained, {comm.allreduce(int(active.sum()), op=MPI.SUM)} in contact"
        N, pins = free_or_refuse(d, R, names, fixed, b, law, load, who, counted)
        # 3-D: Newton on the slip direction, -bound u_t / |u_t| ~ -bound s - bound / |u_t| (I - s s^T) u_t
        blocks = [(tdofs[i], bound[i] / ulen[i] * (np.eye(nt) - np.outer(sdir[i], sdir[i])))
                  for i in np.flatnonzero(slip & (ulen > 0))] if nt > 1 else []
        U, reason = _solve_fixed(A, b, np.r_[dofs, pins], np.r_[values, np.zeros(len(pins))], comm, blocks)
        A.mult(U, r)
        r.axpy(-1.0, b)
        for idx, block in blocks:
            r.array[idx] += block @ U.array[idx]
        free = ~fixed
        free[pins] = False
        resid = comm.allreduce(float(np.max(np.abs(r.array[free]), initial=0.0)), op=MPI.MAX)
        if reason <= 0 or not np.isfinite(resid) or resid > RESIDUAL_TOL * load:
            raise StaticStartError(f"{who}: the static problem is singular (A is not invertible on the free dofs, "
                                   f"beyond the rigid motions; KSP reason {reason}, residual {resid:.2e} of the load "
                                   f"{load:.2e}): no unique static solution; start from a u0 of your own")
        if N.shape[1]:
            no_rigid_displacement(d, U, N, mass_mult)
        A.mult(U, r)
        r.axpy(-1.0, L)                 # the obstacle's reactions: normal, and tangential (friction)
        b.destroy()
        reaction, gap = r.array[d.cdofs], U.array[d.cdofs] - lb
        release = active & (reaction < -RTOL * load)
        add = ~active & (gap < -RTOL * size)
        changes = int(release.sum() + add.sum())
        if law != "none":
            changes += stick_or_slip(friction, r.array[d.cdofs], r.array[tdofs], U.array[tdofs], d.cmeasure,
                                     active & ~release, stick, sdir, bound, ulen, RTOL * load)
        if not comm.allreduce(changes, op=MPI.SUM):
            break
        active = (active & ~release) | add
        stick[add] = True
        U.destroy()
    else:
        raise StaticStartError(f"{who}: the static contact problem found no active set in {MAX_ITER} changes")
    r.destroy(), L.destroy()
    if frame is not None:
        frame.from_frame(U)
    return U
