"""Functions on non-matching meshes: evaluate one mesh's Function at another mesh's points,
in parallel, whatever the two partitions (the disc's convergence study, paper Table 2).

Each point is evaluated on a rank that owns a source cell containing it (or, for a point
just outside a curved boundary that the other mesh approximates differently, the nearest
owned cell within ``padding``); ties go to the lowest rank, so 1 and n ranks agree.
"""
from mpi4py import MPI

import numpy as np
from dolfinx import geometry

from sdm_dolfinx import compat
from sdm_dolfinx.io.reader import PostprocessError


def _owned_cells(msh):
    return np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)


def _owned_bbox(msh):
    """Bounding box (2, 3) of this rank's owned cells' geometry nodes (empty: +inf/-inf)."""
    cells = _owned_cells(msh)
    if not len(cells):
        return np.array([np.full(3, np.inf), np.full(3, -np.inf)])
    nodes = compat.mesh_geometry_dofmap(msh)[cells].reshape(-1)
    x = msh.geometry.x[nodes]
    return np.array([x.min(axis=0), x.max(axis=0)])


def _locate_local(msh, tree, points, padding):
    """For points (n, 3): an owned cell of this rank to evaluate each at, and the point's
    distance to it (0 inside; inf when no owned cell lies within ``padding``)."""
    n = len(points)
    cell = np.full(n, -1, dtype=np.int32)
    dist = np.full(n, np.inf)
    if not n:
        return cell, dist
    coll = compat.colliding_cells(msh, tree, points)
    offsets = coll.offsets
    has = np.diff(offsets) > 0
    cell[has] = coll.array[offsets[:-1][has]]
    dist[has] = 0.0
    missing = np.flatnonzero(~has)
    if len(missing):
        # outside every owned cell (e.g. beyond a curved boundary that the other mesh
        # approximates differently): the nearest owned cell within the padded boxes
        cand = compat.cell_candidates(tree, points[missing])
        for j, p in enumerate(missing):
            cs = cand.links(j)
            if not len(cs):
                continue
            d2 = geometry.squared_distance(msh, msh.topology.dim, cs, np.repeat(points[p:p + 1], len(cs), axis=0))
            k = int(np.argmin(d2))
            if np.sqrt(d2[k]) <= padding:
                cell[p], dist[p] = cs[k], float(np.sqrt(d2[k]))
    return cell, dist


def evaluate_nonmatching(u, points, padding=1e-8):
    """Values of ``u`` at ``points`` (n, 3) given on this rank, whatever the ranks that own
    the cells of ``u``'s mesh containing them (collective).

    Each point goes to the ranks whose owned cells' bounding box (padded) contains it; they
    locate it in an owned cell (bounding-box tree, exact collision) and evaluate there; of
    the answers the one from a containing cell (else the nearest cell within ``padding``,
    which extrapolates) wins, ties to the lowest rank.

    Args:
        u: a Function on a mesh over the same communicator.
        points: (n, 3) array.
        padding: how far outside the source mesh a point may lie (absolute length).

    Returns:
        (values (n, value_size), distance (n,)): distance 0 for points inside the source
        mesh, the distance to the cell used otherwise.

    Raises:
        PostprocessError: a point lies farther than ``padding`` from the source mesh.
    """
    msh = u.function_space.mesh
    comm = msh.comm
    points = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    u.x.scatter_forward()
    vs = int(np.prod(u.ufl_shape)) if u.ufl_shape else 1
    boxes = np.array(comm.allgather(_owned_bbox(msh)))            # (size, 2, 3)
    lo, hi = boxes[:, 0] - padding, boxes[:, 1] + padding
    inside = np.all((points[:, None, :] >= lo[None]) & (points[:, None, :] <= hi[None]), axis=2)  # (n, size)
    send_idx = [np.flatnonzero(inside[:, r]) for r in range(comm.size)]
    recv = comm.alltoall([points[i] for i in send_idx])
    tree = compat.cell_tree(msh, _owned_cells(msh), padding)
    answers = []
    for pts in recv:
        cell, dist = _locate_local(msh, tree, pts, padding)
        vals = np.zeros((len(pts), vs))
        ok = cell >= 0
        if ok.any():
            vals[ok] = u.eval(pts[ok], cell[ok]).reshape(-1, vs)
        answers.append((vals, dist))
    back = comm.alltoall(answers)
    values = np.zeros((len(points), vs))
    best = np.full(len(points), np.inf)
    for r in range(comm.size):            # ascending rank: ties go to the lowest rank
        vals, dist = back[r]
        idx = send_idx[r]
        better = dist < best[idx]
        values[idx[better]] = vals[better]
        best[idx[better]] = dist[better]
    lost = int(comm.allreduce(int(np.sum(~np.isfinite(best))), op=MPI.SUM))
    if lost:
        raise PostprocessError(f"{lost} points lie farther than {padding:g} from the source mesh")
    return values, best


def interpolate_by_points(u_to, u_from, padding=1e-8):
    """Interpolate ``u_from`` (any mesh) into ``u_to``'s space by evaluating it at the
    target element's interpolation points (exact for Lagrange-type elements; collective).

    Returns:
        ``{"max_distance": d}``: the farthest this rank's points lay outside the source mesh.
    """
    stats = {}

    def f(x):
        vals, dist = evaluate_nonmatching(u_from, x.T, padding)
        stats["max_distance"] = float(dist.max(initial=0.0))
        return vals.T if u_from.ufl_shape else vals[:, 0]
    u_to.interpolate(f)
    u_to.x.scatter_forward()
    return stats


def interpolate_nonmatching(u_to, u_from, padding=1e-8):
    """Interpolate ``u_from`` into ``u_to``'s space when the two live on different meshes
    (same communicator, any partitions; collective): dolfinx's own non-matching
    interpolation where it has one (>= 0.7), :func:`interpolate_by_points` otherwise (0.5).

    Returns:
        a dict of statistics: ``max_distance`` on the point-evaluation path, empty otherwise.
    """
    if compat.interpolate_nonmatching(u_to, u_from, padding):
        return {}
    return interpolate_by_points(u_to, u_from, padding)
