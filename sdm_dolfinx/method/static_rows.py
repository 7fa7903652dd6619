"""The equilibrium start on general gap rows: ``u0 = "equilibrium"`` with ``constrain="weighted"``.

The static problem of :mod:`.equilibrium` with the weighted gap's rows G U >= g (:mod:`.weighted_rows`)
instead of bounds on single dofs: find U and multipliers mu with

    A U = L + G^T mu,   G U >= g,  mu >= 0,  mu . (G U - g) = 0,   U = u_D at the Dirichlet dofs.

A row reads several nodes, so no change of variables makes it the bound of one unknown (as the
obstacles' node rows are made in :mod:`.static_frame`): the active rows are held by their multipliers,
the saddle-point system

    [ A     -G_A^T ] [ U  ]   [  L  ]
    [ -G_A   0     ] [ mu ] = [ -g_A ]

(symmetric, indefinite) solved by MUMPS's LU with the Dirichlet dofs eliminated. The active-set loop is
:mod:`.equilibrium`'s: start with the rows touching at U = 0 (the lowest ones if none does), release a
row whose multiplier pulls (mu_i < 0), add one that penetrates (G_i U < g_i), until neither happens. The
free rigid motions are :mod:`.equilibrium`'s too, with "fixed" meaning moved by an active row or a
Dirichlet dof (G_A r != 0): the load must do no work along the others (refused in one line otherwise),
which are pinned for the solve and then removed with the mass (R^T M U = 0). Frictionless only (friction
on the weighted gap is not built yet: refused before this). Started at U_s with zero velocity a run stays
there: the midpoint step's rows are those of the static problem, with the multipliers mu.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.method import static_parts as eq


def static_displacement(d, who):
    """The static displacement U_s (a PETSc vector of W^h) of ``d`` with the weighted gap (the module's
    docstring); ``who`` names the start in errors. Collective.

    Raises:
        StaticStartError: a free rigid motion along which the load works, a singular system, no active
            set in :data:`~.static_parts.MAX_ITER` changes.
    """
    comm, G, g = d.comm, d.weighted_rows.G, d.weighted_rows.g
    L = eq.load_at_zero(d)
    nloc = d.A.getLocalSize()[0]
    load = max(comm.allreduce(float(np.max(np.abs(L.array), initial=0.0)), op=MPI.MAX), np.finfo(float).tiny)
    x = d.problem.mesh.geometry.x
    size = max(comm.allreduce(float(np.ptp(x, axis=0).max()) if len(x) else 0.0, op=MPI.MAX), 1.0)
    R, names = eq.kernel_basis(d, nloc)
    GR = _rows_times(G, R)
    low = comm.allreduce(float(np.min(-g, initial=np.inf)), op=MPI.MIN)      # the rows' gap at U = 0 is -g
    active = -g <= (max(low, 0.0) + eq.RTOL * size)
    fixed = np.zeros(nloc, dtype=bool)
    fixed[d.ddofs] = True
    Gu = G.createVecLeft()
    for _ in range(eq.MAX_ITER):
        N, pins = _free_or_refuse(d, R, GR, names, fixed, active, L, who, load)
        U, mu = _solve(d, G, g, active, L, pins)
        if N.shape[1]:
            eq.no_rigid_displacement(d, U, N, d.mass_mult)
        G.mult(U, Gu)
        gap = Gu.array_r - g
        release = active & (mu < -eq.RTOL * load)
        add = ~active & (gap < -eq.RTOL * size)
        if not comm.allreduce(int(release.sum() + add.sum()), op=MPI.SUM):
            break
        active = (active & ~release) | add
        U.destroy()
    else:
        raise eq.StaticStartError(f"{who}: the static contact problem found no active set in {eq.MAX_ITER} changes")
    Gu.destroy(), L.destroy()
    return U


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


def _free_or_refuse(d, R, GR, names, fixed, active, L, who, load):
    """(the free rigid motions N, owned rows x m; the dofs to pin) when the active rows and the ``fixed``
    (Dirichlet) dofs hold the body; StaticStartError when the load works along a free motion."""
    comm, nloc = d.comm, len(fixed)
    if not R.shape[1]:
        return np.zeros((nloc, 0)), np.zeros(0, dtype=np.int64)
    Rf, Ga = R[fixed], GR[active]
    gram = comm.allreduce(Rf.T @ Rf + Ga.T @ Ga, op=MPI.SUM)
    w, v = np.linalg.eigh(gram)
    coef = v[:, w < eq.FREE_TOL]
    if not coef.size:
        return np.zeros((nloc, 0)), np.zeros(0, dtype=np.int64)
    N = R @ coef
    work = comm.allreduce(N.T @ L.array, op=MPI.SUM)
    bad = np.flatnonzero(np.abs(work) > eq.RTOL * load * np.sqrt(comm.allreduce(nloc, op=MPI.SUM)))
    if bad.size:
        j = bad[np.argmax(np.abs(work[bad]))]
        name = names[int(np.argmax(np.abs(coef[:, j])))]
        raise eq.StaticStartError(
            f"{who}: no static equilibrium: neither the active contact (frictionless, weighted gap) nor Dirichlet "
            f"data fix {name}, and the load works along it (the body would lift off or slide: "
            f"{comm.allreduce(len(active), op=MPI.SUM)} rows, {comm.allreduce(int(active.sum()), op=MPI.SUM)} in "
            f"contact); hold it (Dirichlet data) or start from rest")
    return N, eq.pin_dofs(N, fixed, comm)


def _solve(d, G, g, active, L, pins):
    """(U, mu): the saddle-point system of the module's docstring for the ``active`` rows, the Dirichlet
    dofs and the ``pins`` (U = 0) eliminated; mu on this rank's rows (0 off the active set)."""
    comm = d.comm
    r0 = G.getOwnershipRange()[0]
    rows = PETSc.IS().createGeneral((r0 + np.flatnonzero(active)).astype(PETSc.IntType), comm=comm)
    w0, nw = G.getOwnershipRangeColumn()[0], G.getLocalSize()[1]
    cols = PETSc.IS().createStride(nw, w0, 1, comm=comm)
    Ga = G.createSubMatrix(rows, cols)
    Ga.scale(-1.0)
    GaT = Ga.transpose(PETSc.Mat())
    nest = PETSc.Mat().createNest([[d.A, GaT], [Ga, None]], comm=comm)
    K = nest.convert("aij")
    na = Ga.getLocalSize()[0]
    # the nest's layout: on each rank its W rows, then its active rows
    k0 = K.getOwnershipRange()[0]
    b, sol = K.createVecLeft(), K.createVecRight()
    b.array[:nw] = L.array_r
    b.array[nw:] = -g[active]
    fix = np.concatenate([d.ddofs, pins]).astype(np.int64)
    x0 = K.createVecRight()
    x0.array[d.ddofs] = d.g.x.array[d.ddofs]
    K.zeroRowsColumns((k0 + fix).astype(PETSc.IntType), 1.0, x0, b)
    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(K)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    ksp.solve(b, sol)
    reason = ksp.getConvergedReason()
    U = d.A.createVecRight()
    U.array[:] = sol.array_r[:nw]
    mu = np.zeros(len(g))
    mu[active] = sol.array_r[nw:nw + na]
    for obj in (ksp, K, nest, Ga, GaT, rows, cols, b, sol, x0):
        obj.destroy()
    if reason <= 0 or not np.all(np.isfinite(U.array_r)):
        raise eq.StaticStartError(f"{d.problem.name!r}: u0 = 'equilibrium': the static problem with the weighted "
                                  f"gap is singular (KSP reason {reason}): start from a u0 of your own")
    return U, mu
