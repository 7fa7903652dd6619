"""A Discretisation's Dirichlet parts (:class:`~sdm_dolfinx.problems.dirichlet.DirichletPart`):
their dofs in W^h and their data at a time, evaluated at those dofs (for Lagrange elements, and
at the vertex dofs of P1+, point values are the interpolant's coefficients)."""
from mpi4py import MPI

import numpy as np
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.method import problem_data


def owned_size(W):
    """Number of owned entries (dofs times block size) of W's vectors on this rank."""
    return W.dofmap.index_map.size_local * W.dofmap.index_map_bs


def setup(d):
    """``d.ddofs``: the owned Dirichlet dofs of ``dirichlet_facets`` (every component) and of the
    parts (:func:`locate`); ``d.g``: their values at t = 0; a Dirichlet dof leaves the constraint set."""
    p = d.problem
    W = d.W
    d.ddofs = np.zeros(0, dtype=np.int32)
    d._fixed_ddofs = d.ddofs                      # the constant dirichlet_facets' dofs
    d.g = fem.Function(W)        # Dirichlet values (zero elsewhere; a part's at t = 0)
    # per Dirichlet part (Problem.dirichlet_parts): its owned dofs, their components, the
    # coordinates of its owned dof blocks (part_values)
    d.part_dofs, d.part_components, d._part_x = [], [], []
    if p.dirichlet_facets is None and not p.dirichlet_parts:
        return
    msh = p.mesh
    fdim = msh.topology.dim - 1
    if p.dirichlet_facets is not None:
        facets = np.asarray(p.dirichlet_facets(msh), dtype=np.int32)
        msh.topology.create_connectivity(fdim, msh.topology.dim)
        dofs = fem.locate_dofs_topological(W, fdim, facets)      # blocks
        bs = W.dofmap.index_map_bs
        dofs = (dofs[:, None] * bs + np.arange(bs)[None, :]).reshape(-1)
        gfun = fem.Function(W)
        gfun.interpolate(p.dirichlet_value)
        d.ddofs = d._fixed_ddofs = np.sort(dofs[dofs < owned_size(W)]).astype(np.int32)
        d.g.x.array[d.ddofs] = gfun.x.array[d.ddofs]
    if p.dirichlet_parts:
        locate(d)
        problem_data.refuse(p, d.comm, _contact_refusal(d))
    d.g.x.scatter_forward()
    if np.intersect1d(d.ddofs, d.cdofs).size:
        # a Dirichlet dof is fixed anyway: drop it from the constraint set
        keep = ~np.isin(d.cdofs, d.ddofs)
        d.cverts, d.cdofs, d.lb = d.cverts[keep], d.cdofs[keep], d.lb[keep]
        d.cmeasure, d.q1_of_c, d.cx = d.cmeasure[keep], d.q1_of_c[keep], d.cx[:, keep]
    # collective on every rank (a rank without such a dof must not skip it: deadlock)
    d.num_constraints = d.comm.allreduce(len(d.cdofs), op=MPI.SUM)


def _contact_refusal(d):
    """Why the Dirichlet parts cannot be taken with the constraint, or None (collective): a part that
    prescribes a constrained dof would switch the contact off there (``dirichlet_facets`` keeps
    that older behaviour: a fixed dof leaves the constraint set), however its data compare with
    the bound."""
    for part, dofs in zip(d.problem.dirichlet_parts, d.part_dofs):
        n = d.comm.allreduce(int(np.intersect1d(dofs, d.cdofs).size), op=MPI.SUM)
        if n:
            return (f"Dirichlet part {part.name!r} prescribes the constrained component at {n} constrained points, "
                    f"where it would switch the contact off: leave the contact boundary out of the part (or "
                    f"prescribe only its other components)")
    return None


def locate(d):
    """The owned dofs of each Dirichlet part (its prescribed components of the dof blocks on its
    facets), their values at t = 0 into ``g``, and the union into ``ddofs``. A dof in two parts
    (or in a part and ``dirichlet_facets``) is refused in one line: whose data and reaction it
    carries would be a guess."""
    p, W, msh = d.problem, d.W, d.problem.mesh
    fdim, bs, shape = msh.topology.dim - 1, W.dofmap.index_map_bs, tuple(p.shape)
    msh.topology.create_connectivity(fdim, msh.topology.dim)
    nowned = W.dofmap.index_map.size_local
    taken, wrong = d.ddofs, None
    fmap = msh.topology.index_map(fdim)
    exterior = dmesh.exterior_facet_indices(msh.topology)           # owned facets with one cell
    for part in p.dirichlet_parts:
        facets = np.asarray(part.facets(msh))
        if facets.size and not np.issubdtype(facets.dtype, np.integer):
            wrong = wrong or f"Dirichlet part {part.name!r}: facets returned {facets.dtype} values, not facet indices"
            facets = np.zeros(0, dtype=np.int32)
        refused = _facets_refusal(part.name, facets.reshape(-1), fmap, exterior, d.comm)   # collective: always
        wrong = wrong or refused
        if facets.size and (facets.min() < 0 or facets.max() >= fmap.size_local + fmap.num_ghosts):
            facets = np.zeros(0, dtype=np.int32)
        blocks = fem.locate_dofs_topological(W, fdim, facets.astype(np.int32).reshape(-1))
        blocks = np.sort(blocks[blocks < nowned]).astype(np.int64)
        axes = np.asarray(part.axes(shape), dtype=np.int64)
        dofs = (blocks[:, None] * bs + axes[None, :]).reshape(-1).astype(np.int32)
        if np.intersect1d(dofs, taken).size:
            other = next((q.name for q, qd in zip(p.dirichlet_parts, d.part_dofs)
                          if np.intersect1d(dofs, qd).size), None)
            wrong = wrong or (f"Dirichlet part {part.name!r} shares prescribed dofs with "
                              + (f"part {other!r}" if other else "dirichlet_facets")
                              + ": leave the shared facets (or components) out of one of them")
        d.part_dofs.append(dofs)
        d.part_components.append(np.tile(axes, len(blocks)).astype(np.int32))
        d._part_x.append(d._dof_x()[blocks].T if blocks.size else np.zeros((3, 0)))
        taken = np.union1d(taken, dofs)
    problem_data.refuse(p, d.comm, wrong)
    for k in range(len(p.dirichlet_parts)):
        d.g.x.array[d.part_dofs[k]] = d.part_values(k, 0.0)
    d.ddofs = np.asarray(taken, dtype=np.int32)


def _facets_refusal(name, facets, fmap, exterior, comm):
    """Why Dirichlet part ``name``'s ``facets`` cannot be its facets, or None (collective): none on any
    rank (a locator that matches nothing would prescribe nothing, silently), indices out of range, or
    owned facets that are not on the boundary (vertex indices given for facet indices, say: they
    would prescribe arbitrary facets)."""
    nall = fmap.size_local + fmap.num_ghosts
    out = int(np.count_nonzero((facets < 0) | (facets >= nall)))
    owned = facets[(facets >= 0) & (facets < fmap.size_local)]
    inner = int(np.count_nonzero(~np.isin(owned, exterior)))
    total, out, inner = (comm.allreduce(v, op=MPI.SUM) for v in (int(facets.size), out, inner))
    if not total:
        return (f"Dirichlet part {name!r}: facets(mesh) returned no facet on any rank (it would prescribe "
                f"nothing): check its locator")
    if out or inner:
        return (f"Dirichlet part {name!r}: {out + inner} of the {total} indices facets(mesh) returned are not "
                f"boundary facets ({out} out of range, {inner} inside the body): facets must return facet indices "
                f"on the boundary, e.g. locate_entities_boundary(mesh, tdim - 1, where), not vertex indices")
    return None


def part_values(d, k, t, rate=False):
    """The data of Dirichlet part ``k`` at time ``t`` (``rate``: its velocity) at its owned dofs
    ``part_dofs[k]`` (DiscretisationError on every rank, one line, for data that are not finite
    or of the wrong shape)."""
    p = d.problem
    part, x, shape = p.dirichlet_parts[k], d._part_x[k], tuple(p.shape)
    wrong, v = None, np.zeros(len(d.part_dofs[k]))
    try:
        vals = part.values(x, t, shape, rate)
        axes = list(part.axes(shape)) if shape else [0]
        v = np.ascontiguousarray(vals[axes, :].T).reshape(-1)
        if not np.all(np.isfinite(v)):
            wrong = (f"Dirichlet part {part.name!r}: {'velocity' if rate else 'value'}(x, t) is not finite at "
                     f"t = {t:.6g}")
    except SdmError as e:
        wrong = str(e)
    problem_data.refuse(p, d.comm, wrong)
    return v
