"""The pieces of the static problem that every equilibrium start shares (:mod:`.equilibrium` on bounds of
dofs and in the obstacles' frames, :mod:`.static_rows` on general rows): the tolerances, the error, the
load at t = 0, and the rigid motions A does not resist (which are free, how they are pinned for a solve
and removed after it)."""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
from dolfinx import fem

from sdm_dolfinx import compat
from sdm_dolfinx.method.errors import DiscretisationError

#: the most active-set changes of the loop
MAX_ITER = 100
#: a reaction below -RTOL times the load's size pulls (released); a gap below -RTOL times the mesh's
#: size penetrates (added); the cone and the free motions' load are checked at this relative size too
RTOL = 1e-10
#: a rigid motion r is in A's kernel when |A r|_inf <= KERNEL_TOL |A|_inf |r|_inf
KERNEL_TOL = 1e-9
#: a rigid motion is free when the unit-norm combination's squared norm on the fixed dofs is below this
FREE_TOL = 1e-12
#: the free dofs' residual |A U - L|_inf must be below this times |L|_inf (else A is singular there)
RESIDUAL_TOL = 1e-8


class StaticStartError(DiscretisationError):
    """``u0 = "equilibrium"`` where the static problem has no (unique) solution: one line, exit 2."""


def rigid_modes(d):
    """[(name, vector of W)] of the rigid motions of the problem's unknown: translations and rotations
    (about the mesh's centre) of a vector u of the mesh's dimension, the translations of another vector,
    the constant of a scalar u."""
    p, msh = d.problem, d.problem.mesh
    shape = tuple(p.shape)
    if not shape:
        return [("the constant", d.rigid_vector(0))]
    n, axes = shape[0], "xyz"
    modes = [(f"the translation along {axes[c] if c < 3 else c}", d.rigid_vector(c)) for c in range(n)]
    gdim = msh.geometry.dim
    if n != gdim or gdim < 2:
        return modes
    comm = msh.comm
    x = msh.geometry.x[:, :gdim]
    lo, hi = x.min(axis=0) if len(x) else np.full(gdim, np.inf), x.max(axis=0) if len(x) else np.full(gdim, -np.inf)
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    c = 0.5 * (lo + hi)
    planes = [(0, 1, "z")] if gdim == 2 else [(1, 2, "x"), (2, 0, "y"), (0, 1, "z")]
    for i, j, about in planes:
        def rotation(x, i=i, j=j):
            v = np.zeros((gdim, x.shape[1]))
            v[i], v[j] = -(x[j] - c[j]), x[i] - c[i]
            return v
        f = fem.Function(d.W)
        f.interpolate(rotation)
        modes.append((f"the rotation about {about}", compat.petsc_vec(f).copy()))
    return modes


def kernel(d, modes):
    """The rigid motions A does not resist (A r = 0 to round-off): [(name, r)]."""
    norm_a = d.A.norm(PETSc.NormType.INFINITY)
    out, y = [], d.A.createVecLeft()
    for name, r in modes:
        d.A.mult(r, y)
        if y.norm(PETSc.NormType.INFINITY) <= KERNEL_TOL * norm_a * r.norm(PETSc.NormType.INFINITY):
            out.append((name, r))
        else:
            r.destroy()
    y.destroy()
    return out


def kernel_basis(d, nloc, frame=None):
    """(R: the rigid motions in A's kernel as unit columns, owned rows (in the ``frame``: T^T R); their
    names)."""
    modes = kernel(d, rigid_modes(d))
    R = np.column_stack([r.array for _, r in modes]) if modes else np.zeros((nloc, 0))
    for _, r in modes:
        r.destroy()
    if R.shape[1]:
        R = R / np.sqrt(d.comm.allreduce(np.sum(R * R, axis=0), op=MPI.SUM))
    return (R if frame is None else frame.to_frame_rows(R)), [n for n, _ in modes]


def free_motions(R, fixed, comm, extra=None):
    """The combinations of the columns of R (owned rows, unit columns) that vanish on the ``fixed`` rows
    and, with ``extra`` (this rank's Gram contribution (C R)^T (C R) of rows C that hold the body: the
    weighted gap's), on those rows: (their coefficients, k x m)."""
    Rf = R[fixed]
    G = comm.allreduce(Rf.T @ Rf + (0.0 if extra is None else extra), op=MPI.SUM)
    w, v = np.linalg.eigh(G)
    return v[:, w < FREE_TOL]


def free_or_refuse(d, R, names, fixed, b, law, load, who, counted, kind="", extra=None):
    """(the free rigid motions N: owned rows x m, the dofs to pin to remove them) for the ``fixed`` dofs
    (and the rows of ``extra``: :func:`free_motions`); StaticStartError when the load ``b`` works along one
    of them (no static solution). ``counted``: the constraints and those in contact, for the message;
    ``kind``: the constraint's name in it (e.g. "weighted gap")."""
    comm, nloc = d.comm, len(fixed)
    coef = free_motions(R, fixed, comm, extra) if R.shape[1] else np.zeros((0, 0))
    if not coef.size:
        return np.zeros((nloc, 0)), np.zeros(0, dtype=np.int64)
    N = R @ coef
    work = comm.allreduce(N.T @ b.array, op=MPI.SUM)
    bad = np.flatnonzero(np.abs(work) > RTOL * load * np.sqrt(comm.allreduce(nloc, op=MPI.SUM)))
    if bad.size:
        j = bad[np.argmax(np.abs(work[bad]))]
        name = names[int(np.argmax(np.abs(coef[:, j])))]
        held = (f"the active contact, friction{f' ({kind})' if kind else ''} and Dirichlet data do not fix"
                if law != "none" else f"neither the active contact (frictionless{f', {kind}' if kind else ''}) nor "
                                      f"Dirichlet data fix")
        raise StaticStartError(
            f"{who}: no static equilibrium: {held} {name}, and the load works along it (the body would "
            f"{'lift off or slide' if law == 'none' else 'lift off or slip'}: {counted}); hold it "
            f"({'friction, ' if law == 'none' else ''}Dirichlet data) or start from rest")
    return N, pin_dofs(N, fixed, comm)


def pin_dofs(N, fixed, comm):
    """Owned rows (local indices, on their owner) where pinning U = 0 removes the free motions N (owned
    rows x m): Gaussian elimination with complete pivoting, the pivot sought over every rank."""
    N = N.copy()
    N[fixed] = 0.0
    rank, pins = comm.rank, []
    m = N.shape[1]
    cols = list(range(m))
    for _ in range(m):
        sub = np.abs(N[:, cols]) if len(N) else np.zeros((0, len(cols)))
        k = np.unravel_index(np.argmax(sub), sub.shape) if sub.size else (-1, -1)
        best, owner = comm.allreduce((float(sub[k]) if sub.size else -1.0, rank), op=MPI.MAXLOC)
        row = comm.bcast(N[k[0]].copy() if rank == owner else None, root=owner)
        col = cols[int(comm.bcast(k[1] if rank == owner else None, root=owner))]
        if rank == owner:
            pins.append(int(k[0]))
        cols.remove(col)
        if cols:
            N[:, cols] -= np.outer(N[:, col] / row[col], row[cols])
        N[:, col] = 0.0
    return np.array(pins, dtype=np.int64)


def load_at_zero(d):
    """L at t = 0 (a new vector; a time-dependent load's ``time`` is restored)."""
    p = d.problem
    if p.time is None:
        return d.L.copy()
    t = float(p.time.value)
    p.time.value = 0.0
    L = compat.assemble_vector(d.L_form)
    p.time.value = t
    return L


def no_rigid_displacement(d, U, N, mass_mult):
    """U -= N c with (M N)^T U = 0 after: no rigid displacement along the free motions N (the centre
    of mass does not move along them); ``mass_mult(x, y)``: y = M x."""
    comm, MN = d.comm, []
    for j in range(N.shape[1]):
        nj, mj = U.duplicate(), U.duplicate()
        nj.array[:] = N[:, j]
        mass_mult(nj, mj)
        MN.append(mj.array.copy())
        nj.destroy(), mj.destroy()
    MN = np.column_stack(MN)
    c = np.linalg.solve(comm.allreduce(MN.T @ N, op=MPI.SUM), comm.allreduce(MN.T @ U.array, op=MPI.SUM))
    U.array[:] -= N @ c


def stick_or_slip(friction, lam_n, lam_t, ut, measure, active, stick, sdir, bound, ulen, tol):
    """One update of the stick and slip sets (in place) after a static solve; the number of changes.

    A sticking dof whose tangential reaction leaves the cone (|r_t| > bound, Coulomb mu r_n, Tresca
    s m_i) slips from now on, along -r_t / |r_t| with the reaction -bound s; a slipping dof whose
    displacement u_t went against its slip direction (u_t . s <= 0) sticks again; a slipping dof takes
    the direction of u_t (3-D) and the bound of the new normal reaction (Coulomb): a change of either
    beyond ``tol`` counts, so the loop ends at a fixed point. ``lam_n`` (m,), ``lam_t`` and ``ut`` (m x
    (gdim - 1)): the normal and tangential reactions and the tangential displacements of the m contact
    unknowns (dofs, or rows); ``measure``: their nodal measures (Tresca's s m_i)."""
    new = (friction.mu * np.maximum(lam_n, 0.0) if friction.law == "coulomb"
           else friction.threshold * measure)
    norm_t = np.linalg.norm(lam_t, axis=1)
    slipping = active & ~stick
    to_slip = active & stick & (norm_t > new + tol)
    dot = np.sum(ut * sdir, axis=1)
    to_stick = slipping & (dot <= 0.0)
    keep = slipping & ~to_stick
    norm_u = np.linalg.norm(ut, axis=1)
    turn = np.zeros(len(stick))
    if keep.any():
        s_new = ut[keep] / norm_u[keep, None]
        turn[keep] = np.linalg.norm(s_new - sdir[keep], axis=1) * new[keep]
        sdir[keep], ulen[keep] = s_new, norm_u[keep]
    moved = keep & ((np.abs(new - bound) > tol) | (turn > tol))
    sdir[to_slip], ulen[to_slip | to_stick] = -lam_t[to_slip] / norm_t[to_slip, None], 0.0
    stick[to_slip], stick[to_stick] = False, True
    bound[:] = new
    return int(to_slip.sum() + to_stick.sum() + moved.sum())


def lu_solve(K, b, u):
    """u = K^-1 b by MUMPS's LU (one factorisation, destroyed after); the KSP's converged reason."""
    ksp = PETSc.KSP().create(K.getComm())
    ksp.setOperators(K)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    ksp.solve(b, u)
    reason = ksp.getConvergedReason()
    ksp.destroy()
    return reason
