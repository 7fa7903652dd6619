"""The equilibrium start on general gap rows: ``u0 = "equilibrium"`` with ``constrain="weighted"``.

The static problem of :mod:`.equilibrium` with the weighted gap's rows G U >= g (:mod:`.weighted_rows`)
instead of bounds on single dofs: find U and multipliers mu with

    A U = L + G^T mu,   G U >= g,  mu >= 0,  mu . (G U - g) = 0,   U = u_D at the Dirichlet dofs.

A row reads several nodes, so no change of variables makes it the bound of one unknown (as the
obstacles' node rows are made in :mod:`.static_frame`): the active rows are held by their multipliers,
the saddle-point system

    [ A     -C^T ] [ U  ]   [ L + f ]
    [ -C     0   ] [ mu ] = [ -c    ]

(symmetric, indefinite) solved by MUMPS's LU with the Dirichlet dofs eliminated; C holds the active
normal rows (C U = g there). The active-set loop is :mod:`.equilibrium`'s: start with the rows touching
at U = 0 (the lowest ones if none does), release a row whose multiplier pulls (mu_i < 0), add one that
penetrates (G_i U < g_i), until neither happens.

**With friction** (Coulomb, Tresca) the tangential rows H_(i,t) (the same weights on a tangential
component: :mod:`sdm_dolfinx.solvers.friction_rows`) are the tangential unknowns, as the tangential dofs
are in :mod:`.equilibrium`: an active row sticks (H_i U = 0: C holds its tangential rows too, their
multipliers the tangential reactions) while its reaction lies in the cone, else it slips with the force
f = -bound H_i^T s (on the right-hand side above) on the cone's edge (3-D: with the Newton term bound / |u_t| (I - s s^T) on its
tangential rows, H_i^T B_i H_i added to A); the sets are updated by
:func:`~.static_parts.stick_or_slip`, the same rule.

The free rigid motions are :mod:`.equilibrium`'s too, with "fixed" meaning moved by a row of C or a
Dirichlet dof (C r != 0): the load must do no work along the others (refused in one line otherwise),
which are pinned for the solve and then removed with the mass (R^T M U = 0). Started at U_s with zero
velocity a run stays there: the midpoint step's rows are those of the static problem, with the
multipliers mu.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.method import static_parts as eq
from sdm_dolfinx.solvers.friction_rows import component_rows


def _shifted(G, component, k):
    """The rows of G (entries on ``component``'s dofs) with the same weights on component ``k``'s dofs
    (a new PETSc matrix of G's layout)."""
    local = component_rows(G, component, k)
    csr = (local.indptr.astype(PETSc.IntType), local.indices.astype(PETSc.IntType), local.data)
    H = PETSc.Mat().createAIJ(G.getSizes(), csr=csr, comm=G.getComm())
    H.assemble()
    return H


def static_displacement(d, who, friction=None):
    """The static displacement U_s (a PETSc vector of W^h) of ``d`` with the weighted gap (the module's
    docstring); ``friction`` (``law``, ``mu``, ``threshold``) or None; ``who`` names the start in errors.
    Collective.

    Raises:
        StaticStartError: a free rigid motion along which the load works, a singular system, no active
            set in :data:`~.static_parts.MAX_ITER` changes.
    """
    comm, G, g = d.comm, d.weighted_rows.G, d.weighted_rows.g
    law = getattr(friction, "law", "none") if friction is not None else "none"
    comp = d.problem.constraint_component or 0
    axes = [k for k in range(d.problem.shape[0]) if k != comp] if law != "none" else []
    H = [_shifted(G, comp, k) for k in axes]
    L = eq.load_at_zero(d)
    nloc = d.A.getLocalSize()[0]
    load = max(comm.allreduce(float(np.max(np.abs(L.array), initial=0.0)), op=MPI.MAX), np.finfo(float).tiny)
    x = d.problem.mesh.geometry.x
    size = max(comm.allreduce(float(np.ptp(x, axis=0).max()) if len(x) else 0.0, op=MPI.MAX), 1.0)
    R, names = eq.kernel_basis(d, nloc)
    GR, HR = _rows_times(G, R), [_rows_times(h, R) for h in H]
    low = comm.allreduce(float(np.min(-g, initial=np.inf)), op=MPI.MIN)      # the rows' gap at U = 0 is -g
    active = -g <= (max(low, 0.0) + eq.RTOL * size)
    m, nt = len(g), len(axes)
    stick = np.ones(m, dtype=bool)              # with friction: an active row sticks, or slips along sdir
    sdir, bound, ulen = np.zeros((m, nt)), np.zeros(m), np.zeros(m)
    fixed = np.zeros(nloc, dtype=bool)
    fixed[d.ddofs] = True
    measure = np.asarray(d.cmeasure, dtype=float)
    try:
        for _ in range(eq.MAX_ITER):
            held = active & stick if nt else np.zeros(m, dtype=bool)
            slip = active & ~stick if nt else np.zeros(m, dtype=bool)
            b = L.copy()                            # the load, and the friction force -bound H^T s where it slips
            for k, h in enumerate(H):
                f = _vec(h, np.where(slip, -bound * sdir[:, k], 0.0))
                h.multTransposeAdd(f, b, b)
                f.destroy()
            extra = sum(c[mask].T @ c[mask] for c, mask in zip([GR] + HR, [active] + [held] * nt))
            counted = (f"{comm.allreduce(m, op=MPI.SUM)} rows, {comm.allreduce(int(active.sum()), op=MPI.SUM)} "
                       f"in contact")
            N, pins = eq.free_or_refuse(d, R, names, fixed, b, law, load, who, counted, "weighted gap", extra)
            blocks = [(i, bound[i] / ulen[i] * (np.eye(nt) - np.outer(sdir[i], sdir[i])))
                      for i in np.flatnonzero(slip & (ulen > 0))] if nt > 1 else []
            U, mu = _solve(d, [G] + H, [g] + [np.zeros(m)] * nt, [active] + [held] * nt, b, pins, blocks)
            if N.shape[1]:
                eq.no_rigid_displacement(d, U, N, d.mass_mult)
            b.destroy()
            gap = _rows(G, U) - g
            release = active & (mu[0] < -eq.RTOL * load)
            add = ~active & (gap < -eq.RTOL * size)
            changes = int(release.sum() + add.sum())
            if nt:
                ut = np.column_stack([_rows(h, U) for h in H])
                lam_t = np.column_stack(mu[1:])     # the sticking rows' (stick_or_slip reads no other)
                changes += eq.stick_or_slip(friction, mu[0], lam_t, ut, measure, active & ~release, stick, sdir,
                                            bound, ulen, eq.RTOL * load)
            if not comm.allreduce(changes, op=MPI.SUM):
                break
            active = (active & ~release) | add
            stick[add] = True
            U.destroy()
        else:
            raise eq.StaticStartError(f"{who}: the static contact problem found no active set in {eq.MAX_ITER} "
                                      f"changes")
    finally:
        L.destroy()
        for h in H:
            h.destroy()
    return U


def _vec(M, values):
    """A PETSc vector of M's row layout holding ``values`` (this rank's rows)."""
    v = M.createVecLeft()
    v.array[:] = values
    return v


def _rows(M, U):
    """M U at this rank's rows (a copy)."""
    y = M.createVecLeft()
    M.mult(U, y)
    out = y.array_r.copy()
    y.destroy()
    return out


def _rows_times(G, R):
    """G R (this rank's rows x the columns of R, owned rows of W)."""
    x, y = G.createVecRight(), G.createVecLeft()
    out = np.zeros((G.getLocalSize()[0], R.shape[1]))
    for j in range(R.shape[1]):
        x.array[:] = R[:, j]
        G.mult(x, y)
        out[:, j] = y.array_r
    x.destroy(), y.destroy()
    return out


def _solve(d, Cs, cs, masks, b, pins, blocks=()):
    """(U, [mu per matrix]): the saddle-point system of the module's docstring with C the rows of the
    matrices ``Cs`` under ``masks`` (values ``cs``), the Dirichlet dofs and the ``pins`` (U = 0)
    eliminated; ``blocks`` [(row i, B)]: B_kl H_k[i]^T H_l[i] added to A (Cs[1:] are the H_k). Each mu on
    this rank's rows (0 off its mask)."""
    comm = d.comm
    w0, nw = Cs[0].getOwnershipRangeColumn()[0], Cs[0].getLocalSize()[1]
    cols = PETSc.IS().createStride(nw, w0, 1, comm=comm)
    subs = []
    for C, mask in zip(Cs, masks):
        r0 = C.getOwnershipRange()[0]
        rows = PETSc.IS().createGeneral((r0 + np.flatnonzero(mask)).astype(PETSc.IntType), comm=comm)
        sub = C.createSubMatrix(rows, cols)
        sub.scale(-1.0)
        subs.append(sub)
        rows.destroy()
    Cm = PETSc.Mat().createNest([[s] for s in subs], comm=comm)
    Ca = Cm.convert("aij")
    CaT = Ca.transpose(PETSc.Mat())
    A = d.A
    if comm.allreduce(len(blocks), op=MPI.SUM):     # collective: a rank without slipping rows assembles too
        A = d.A.copy()
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        _add_blocks(A, Cs[1:], blocks)
    nest = PETSc.Mat().createNest([[A, CaT], [Ca, None]], comm=comm)
    K = nest.convert("aij")
    na = Ca.getLocalSize()[0]
    k0 = K.getOwnershipRange()[0]
    rhs, sol = K.createVecLeft(), K.createVecRight()
    rhs.array[:nw] = b.array_r
    rhs.array[nw:] = -np.concatenate([c[mask] for c, mask in zip(cs, masks)])
    fix = np.concatenate([d.ddofs, pins]).astype(np.int64)
    x0 = K.createVecRight()
    x0.array[d.ddofs] = d.g.x.array[d.ddofs]
    # MatZeroRowsColumns needs each row's diagonal entry in the sparsity (PETSc 3.25 refuses one the nest's
    # conversion left out: "missing diagonal entry"): an explicit 0 added first
    K.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    for r in (k0 + fix).tolist():
        K.setValue(r, r, 0.0, addv=PETSc.InsertMode.ADD_VALUES)
    K.assemble()
    K.zeroRowsColumns((k0 + fix).astype(PETSc.IntType), 1.0, x0, rhs)
    reason = eq.lu_solve(K, rhs, sol)
    # the solve's residual, by block (forces, gaps) against its right-hand side's size: a nearly singular
    # system (an active row reading Dirichlet dofs only, a free motion missed) is refused, not returned
    res = K.createVecLeft()
    K.mult(sol, res)
    res.axpy(-1.0, rhs)
    worst = [comm.allreduce(float(np.max(np.abs(v), initial=0.0)), op=MPI.MAX)
             for v in (res.array_r[:nw], rhs.array_r[:nw], res.array_r[nw:], rhs.array_r[nw:])]
    res.destroy()
    singular = not (worst[0] <= eq.RESIDUAL_TOL * max(worst[1], np.finfo(float).tiny)
                    and worst[2] <= eq.RESIDUAL_TOL * max(worst[3], 1.0))
    U = d.A.createVecRight()
    U.array[:] = sol.array_r[:nw]
    mus, pos = [], nw
    for c, mask in zip(cs, masks):
        mu = np.zeros(len(c))
        mu[mask] = sol.array_r[pos:pos + int(mask.sum())]
        pos += int(mask.sum())
        mus.append(mu)
    for obj in (K, nest, Cm, Ca, CaT, cols, rhs, sol, x0, *subs):
        obj.destroy()
    if A is not d.A:
        A.destroy()
    finite = comm.allreduce(bool(np.all(np.isfinite(U.array_r))), op=MPI.LAND)
    if reason <= 0 or not finite or singular or pos != nw + na:
        raise eq.StaticStartError(f"{d.problem.name!r}: u0 = 'equilibrium': the static problem with the weighted "
                                  f"gap is singular (KSP reason {reason}, residual {worst[0]:.2e} of the load "
                                  f"{worst[1]:.2e}): start from a u0 of your own")
    return U, mus


def _add_blocks(A, H, blocks):
    """A += sum over the (row i, B) of ``blocks`` of sum_kl B_kl H_k[i]^T H_l[i] (this rank's rows i of the
    tangential row matrices ``H``; the products' entries may be other ranks' rows: added, assembled)."""
    r0 = H[0].getOwnershipRange()[0]
    for i, B in blocks:
        rows = [H[k].getRow(r0 + i) for k in range(len(H))]
        for k, (ck, vk) in enumerate(rows):
            for j, (cj, vj) in enumerate(rows):
                if B[k, j] != 0.0:
                    A.setValues(ck.astype(PETSc.IntType), cj.astype(PETSc.IntType),
                                np.ascontiguousarray(B[k, j] * np.outer(vk, vj)), addv=PETSc.InsertMode.ADD_VALUES)
    A.assemble()
