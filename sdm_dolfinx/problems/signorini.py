"""The static Signorini problem of a body resting on the foundation y = 0 (a problem's u0).

A u = L with unilateral contact u_y >= -y at given boundary vertices, solved by an active-set
loop of linear solves (dolfinx assembly, PETSc elimination of the fixed dofs, MUMPS): the
disc's ``--start equilibrium``. Every array of the loop (the candidate vertices' dofs, bounds,
reactions, gaps) is the same on every rank, so the active set is partition-independent.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx import compat

#: the quadrature degree of the static forms: the run's automatic degree on curved cells
#: (method.quadrature.CURVED_DEGREE, the disc's P2 geometry), so that A and L are the run's to
#: round-off (another --quadrature-degree leaves an equilibrium to ~1e-6 relative: the table of
#: method/quadrature.py)
QUADRATURE = 12
#: the most active-set changes of the loop (the disc: 1 solve on level 1, 2 on level 2)
MAX_ITER = 50


def _vertex_blocks(V, verts):
    """Global block (node) index of V at each local mesh vertex of ``verts`` (the vertex entity
    dofs: P1, P1+ and P2 alike)."""
    msh = V.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    cell_vertices = msh.topology.connectivity(tdim, 0).array.reshape(-1, tdim + 1)
    dofs = compat.dofmap_list(V)
    v2d = np.full(msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts, -1, dtype=np.int32)
    for k in range(tdim + 1):
        (ldof,) = V.dofmap.dof_layout.entity_dofs(0, k)
        v2d[cell_vertices[:, k]] = dofs[:, ldof]
    return V.dofmap.index_map.local_to_global(v2d[np.asarray(verts, dtype=np.int32)]).astype(np.int64)


def _vertices_everywhere(V, verts):
    """(global u_y dofs, x, y) of the local vertices ``verts`` of every rank, sorted by dof and
    without repeats (a vertex on several ranks, ghosted, is one): the same arrays on every rank."""
    msh = V.mesh
    x = (msh.geometry.x[compat.entities_to_geometry(msh, 0, np.asarray(verts, dtype=np.int32)).reshape(-1)]
         if len(verts) else np.zeros((0, 3)))
    dofs = np.concatenate(msh.comm.allgather(2 * _vertex_blocks(V, verts) + 1))
    xy = np.concatenate(msh.comm.allgather(x[:, :2]))
    dofs, first = np.unique(dofs, return_index=True)
    return dofs, xy[first, 0], xy[first, 1]


def _nearest_x_dof(V, point):
    """The global u_x dof of the mesh vertex nearest to ``point`` (the same on every rank)."""
    msh = V.mesh
    dofs, x, y = _vertices_everywhere(V, np.arange(msh.topology.index_map(0).size_local, dtype=np.int32))
    return int(dofs[np.argmin(np.hypot(x - point[0], y - point[1]))] - 1)


def _owned_values(vec, dofs):
    """``vec``'s entries at the global indices ``dofs``, on every rank (each owner fills its own)."""
    lo, hi = vec.getOwnershipRange()
    own = (dofs >= lo) & (dofs < hi)
    out = np.zeros(len(dofs))
    out[own] = vec.getArray(readonly=True)[dofs[own] - lo]
    vec.getComm().tompi4py().Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
    return out


def _solve_fixed(A, L, dofs, values):
    """A u = L with u = ``values`` at the global indices ``dofs`` (the same on every rank), by
    symmetric elimination of those dofs and MUMPS."""
    lo, hi = A.getOwnershipRange()
    own = (dofs >= lo) & (dofs < hi)
    rows = dofs[own].astype(PETSc.IntType)
    x0, b, u = A.createVecRight(), L.copy(), A.createVecRight()
    x0.setValues(rows, np.asarray(values, dtype=PETSc.ScalarType)[own])
    x0.assemble()
    K = A.copy()
    K.zeroRowsColumns(rows, 1.0, x0, b)
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOperators(K)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    ksp.solve(b, u)
    reason = ksp.getConvergedReason()
    ksp.destroy(), K.destroy(), b.destroy(), x0.destroy()
    if reason <= 0:
        raise RuntimeError(f"the static contact solve failed (KSP reason {reason})")
    return u


def resting_solution(msh, element, a, l, verts, pins, scale):
    """The body resting on the foundation: the static displacement in ``element`` (a 2-D vector
    element) under the load ``l`` with unilateral contact u_y >= -y at the vertices ``verts``
    (local vertex indices on this rank), by a Signorini active-set loop of linear solves.

    Active vertices hold u_y = -y (touching). The loop starts with the lowest vertices, then
    releases the active vertices whose reaction (A u - L)_y is tensile and adds the inactive ones
    that penetrate, until neither happens: every reaction is then >= 0 (compressive, the
    method's lam), every gap >= 0, and the reactions sum to the load's normal part. u_x = 0 at
    the vertex nearest to ``pins[0]`` removes the rigid translation along x; while the active
    vertices share one x (the disc's point A alone: its coarse levels) the rotation about it is
    free too, and u_x = 0 at the vertex nearest to ``pins[1]`` (the disc's top) removes it: for
    a load symmetric about the vertical through ``pins[0]`` that is the symmetric solution,
    whose reaction at ``pins[1]`` vanishes but for the mesh's asymmetry (the disc, levels 1 and
    2: see docs/friction_problems.md). ``scale`` (a length: the disc's radius) sets the
    tolerances: a gap below -1e-12 scale penetrates; a reaction below -1e-12 of the load pulls.
    The forms are compiled at :data:`QUADRATURE`. Collective.

    Returns:
        the static displacement, a ``fem.Function`` of ``element``.
    """
    V = compat.function_space(msh, element)
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    A = compat.assemble_matrix(compat.form(a(u, w), quadrature_degree=QUADRATURE))
    L = compat.assemble_vector(compat.form(l(w), quadrature_degree=QUADRATURE))
    ydofs, x, y = _vertices_everywhere(V, verts)
    pin_a, pin_top = (_nearest_x_dof(V, p) for p in pins)
    load = abs(L.sum())
    active = y <= y.min() + 1e-8 * scale
    r = A.createVecLeft()
    for _ in range(MAX_ITER):
        pinned = [pin_a] + ([pin_top] if np.ptp(x[active]) <= 1e-8 * scale else [])
        U = _solve_fixed(A, L, np.r_[ydofs[active], pinned], np.r_[-y[active], np.zeros(len(pinned))])
        A.mult(U, r)
        r.axpy(-1.0, L)
        reaction, gap = _owned_values(r, ydofs), _owned_values(U, ydofs) + y
        release, add = active & (reaction < -1e-12 * load), ~active & (gap < -1e-12 * scale)
        if not (release.any() or add.any()):
            break
        active = (active & ~release) | add
        U.destroy()
    else:
        raise RuntimeError(f"the static contact problem found no active set in {MAX_ITER} changes")
    us = fem.Function(V)
    us.x.array[:V.dofmap.index_map.size_local * V.dofmap.index_map_bs] = U.getArray(readonly=True)
    us.x.scatter_forward()
    U.destroy(), r.destroy(), A.destroy(), L.destroy()
    return us
