"""The master side of a contact pair (:class:`~sdm_dolfinx.problems.contact_pairs.ContactPair`): its
facets and their vertices' dofs, gathered on every rank, and the closest-point projection of slave
points on the deformed surface.

**What is gathered.** Once per run each rank sends, for its master facets (exterior facets belong to
the rank holding their cell: the facet's owner), the facet's reference vertex coordinates and the
global block numbers of W^h's nodes at its vertices: every rank holds the surface's reference
geometry (an allgather of O(master facets) numbers), from which the vertex normals and the rim are
computed. **Per projection** a rank gets the deformed facets near its own slave points only
(:meth:`MasterSurface.nearby`): the facets' owners update their vertices' displacements from the
neighbouring ranks (one halo exchange of W^h), every rank's box of its points is allgathered (6
numbers a rank), and each owner sends each rank the facets whose deformed bounding box meets that
box grown by the reach r (an alltoall of the facets' numbers and vertex displacements, nv (1 + gdim)
numbers a facet); then r is checked (an allreduce of one number): the search below gives the
answer of the whole surface when every point's CANDIDATES-th nearest facet centroid among those
received is within r (every facet that can be among its nearest, or nearer than its first answer,
was received: its first answer is within that distance, and the exact search looks no farther); if
not, r grows to the largest such distance and the facets are sent again, which then holds (where a
rank got fewer than CANDIDATES facets, r first doubles and reaches past the surface's bounding box).
r starts each projection from the last one's need (times 1.25), so in a steady contact one round does.

**The master held at its vertices.** The deformed master facet is the simplex of its deformed vertices
x_v + u_v (P2's mid-edge nodes do not bend it: its chord), and the master displacement at a point of
barycentric coordinates xi in it is sum_v xi_v u_v: a row reads the master's vertex dofs only, as the
slave is held at its vertices (eq. (13)). Measured: the facet's own P2 shape functions (mid-edge nodes
included, xi_i (2 xi_i - 1) and 4 xi_i xi_j) make the P2/P1 step unstable wherever a slave vertex
meets a master facet between its vertices (two plane bars on non-matching meshes, head on: the energy
grows 5.4 times at dt = h/(2c), 10.4 times at dt/4), the vertex weights conserve it (0.6 %, 0.4 %).

**The normal.** The continuous field n(xi) = the master vertices' pseudo-normals (the sum of the
adjacent facets' outward unit normals; angle-weighted in 3-D) interpolated over the facet, in the
**reference configuration**: a linear elastic body rotates by less than the model's range (run/
linear_range.py), and the normals of the deformed P2 surface carry the jitter of the singular mass's
massless modes. Measured on two discs head on (demos/two_discs_problem.py, P2/P1): the same field
built on the deformed vertices makes the energy grow 1350 times at level 1 and dt = 2.5e-5 s, 6 times
at level 3 and dt = 1e-4 s (a facet's own normal, which jumps where a slave vertex crosses a master
vertex, as much); the reference field keeps the energy within 2 % at every level and step tried, and
the contact force within 3 % of the single disc's on its plane (tests/physics/test_two_bodies.py;
the price: at an off-centre contact vertex the normal keeps the undeformed surface's tilt, x/R, where
the flattened contact zone's is 0). The projection (which facet, xi) and the gap are those of the
deformed surface: phi = n . (y - q), q the closest point of the slave point y on it.
"""
from __future__ import annotations

from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
from dolfinx import fem
from dolfinx import mesh as dmesh
from scipy.spatial import cKDTree

from sdm_dolfinx import compat
from sdm_dolfinx.method.dofs import vertex_coordinates
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.obstacles.closest import on_segments, on_triangles
from sdm_dolfinx.obstacles.surface_mesh import pseudo_normals
from sdm_dolfinx.problems.base import label

Array = npt.NDArray[np.float64]
#: a slave point is projected on the CANDIDATES facets of nearest centroids, and exactly (every facet that
#: can be nearer) when it is within NEAR sizes of the best of them
CANDIDATES = 8
NEAR = 2.0
#: the reach of the next projection: the last one's need times this
REACH_GROWTH = 1.25
#: a slave point whose closest point is on the surface's rim and which lies more than this many facet sizes
#: off to the side of it is beyond the surface (no row)
RIM = 1e-2


def _unit(v: Array) -> Array:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.asarray(v / np.where(n > 0, n, 1.0))


def facet_normals(corners: Array) -> Array:
    """Unit normals (nf, 3) of facets whose corners (nf, nv, 3) are ordered by the convention of
    :func:`~sdm_dolfinx.obstacles.surface_mesh.element_normals` (2-D: (t_y, -t_x); 3-D: (b - a) x (c - a))."""
    t = corners[:, 1] - corners[:, 0]
    if corners.shape[1] == 2:
        return _unit(np.column_stack([t[:, 1], -t[:, 0], 0.0 * t[:, 0]]))
    return _unit(np.cross(t, corners[:, 2] - corners[:, 0]))


def barycentric(points: Array, corners: Array) -> Array:
    """Barycentric coordinates (n, nv) of points (n, 3) in the simplices corners (n, nv, 3), the points
    projected on each simplex's plane (least squares)."""
    E = np.swapaxes(corners[:, 1:] - corners[:, :1], 1, 2)          # (n, 3, nv - 1)
    rhs = np.einsum("nji,nj->ni", E, points - corners[:, 0])
    lam = np.linalg.solve(np.einsum("nji,njk->nik", E, E), rhs[..., None])[..., 0]
    return np.column_stack([1.0 - lam.sum(axis=1), lam])


def _best(y: Array, point: npt.NDArray[np.int64], facet: npt.NDArray[np.int64],
          cur: Array) -> tuple[Array, Array, Array]:
    """(closest points (m, 3), facets (m,), distances (m,)) of the points y over the pairs (point, facet)
    (every point in at least one pair)."""
    corners = [cur[facet, j] for j in range(cur.shape[1])]
    q = (on_segments(y[point], *corners) if cur.shape[1] == 2 else on_triangles(y[point], *corners))[0]
    d = np.linalg.norm(y[point] - q, axis=1)
    order = np.lexsort((d, point))
    first = order[np.searchsorted(point[order], np.arange(len(y)))]
    return q[first], facet[first], d[first]


def _rim(cells: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
    """(nf, nv): whether the facet's side opposite each corner lies on the surface's open boundary (2-D:
    the side opposite corner j is the vertex 1 - j, on the rim when it ends one facet only; 3-D: the edge
    of the two other corners, on the rim when one facet only has it)."""
    nf, nv = cells.shape
    if nv == 2:
        count = np.bincount(cells.reshape(-1), minlength=int(cells.max(initial=-1)) + 1)
        return count[cells[:, ::-1]] == 1
    edges = np.sort(np.stack([cells[:, [1, 2]], cells[:, [2, 0]], cells[:, [0, 1]]], axis=1), axis=2)
    _, inverse, count = np.unique(edges.reshape(-1, 2), axis=0, return_inverse=True, return_counts=True)
    return (count[inverse.reshape(-1)] == 1).reshape(nf, 3)


class MasterSurface:
    """The master facets of one contact pair, gathered on every rank (see the module).

    Attributes:
        points: (nv_surface, 3) reference coordinates of the surface's vertices.
        cells: (nf, nv) each facet's vertices (indices into ``points``), ordered so that
            :func:`facet_normals` is outward.
        blocks: (nf, nv) the global block numbers of W^h's nodes at them.
        dofs: (nd,) the global dofs of W^h the surface reads (sorted; blocks times the block size plus
            the components).
        at: (nf, nv, gdim) the positions of each facet vertex's dofs in ``dofs``.
        vertex_normals: (nv_surface, 3) the vertices' unit pseudo-normals, reference configuration.
    """

    def __init__(self, d: Any, facets_of: Any, name: str) -> None:
        p, W, comm = d.problem, d.W, d.comm
        msh = p.mesh
        tdim, bs = msh.topology.dim, W.dofmap.index_map_bs
        fdim, nv = tdim - 1, tdim
        self.comm, self.bs, self.gdim = comm, bs, int(p.shape[0])
        if tdim == 1:
            raise DiscretisationError(f"{label(p)}: contact pairs in 1-D are not built (2-D and 3-D meshes)")
        facets = np.unique(np.asarray(facets_of(msh), dtype=np.int64).reshape(-1))
        msh.topology.create_connectivity(fdim, tdim)
        exterior = np.asarray(dmesh.exterior_facet_indices(msh.topology), dtype=np.int64)
        nfl = msh.topology.index_map(fdim).size_local + msh.topology.index_map(fdim).num_ghosts
        wrong = None
        if facets.size and (facets.min() < 0 or facets.max() >= nfl):
            wrong = f"contact pair {name!r}: master returned facet indices outside 0..{nfl - 1}"
        elif not np.all(np.isin(facets, exterior)):
            wrong = f"contact pair {name!r}: master names {int(np.sum(~np.isin(facets, exterior)))} interior facets"
        facets = facets[np.isin(facets, exterior)] if wrong is None else np.zeros(0, dtype=np.int64)
        try:
            corners, blocks, local_blocks = self._local(d, facets.astype(np.int32), fdim, nv)
        except DiscretisationError as e:
            corners, blocks, wrong = np.zeros((0, nv, 3)), np.zeros((0, nv), dtype=np.int64), str(e)
            local_blocks = blocks
        found = [m for m in comm.allgather(wrong) if m]
        if found:
            raise DiscretisationError(f"{label(p)}: {found[0]}")
        counts = comm.allgather(len(corners))
        #: this rank's facets (indices into the gathered ones) and the local dofs of W^h (owned or ghost) at
        #: their vertices (n, nv, gdim)
        self._mine = sum(counts[:comm.rank]) + np.arange(counts[comm.rank], dtype=np.int64)
        self._mine_dofs = (np.asarray(local_blocks, dtype=np.int64)[..., None] * bs + np.arange(self.gdim))
        self._field = fem.Function(d.W)         # this rank's values with its ghosts' (a halo exchange)
        self._owned = W.dofmap.index_map.size_local * bs
        corners = np.concatenate(comm.allgather(corners))
        self.blocks = np.concatenate(comm.allgather(blocks)).astype(np.int64)
        if not len(corners):
            raise DiscretisationError(f"{label(p)}: contact pair {name!r}: master names no exterior facet")
        comps = np.arange(self.gdim)
        self.dofs = np.unique((self.blocks[..., None] * bs + comps).reshape(-1))
        lo, hi = W.dofmap.index_map.local_range
        self._own = (self.dofs >= lo * bs) & (self.dofs < hi * bs)
        self._local_dofs = (self.dofs[self._own] - lo * bs).astype(np.int64)
        self.at = np.searchsorted(self.dofs, self.blocks[..., None] * bs + comps)
        _, first, cells = np.unique(self.blocks.reshape(-1), return_index=True, return_inverse=True)
        self.points = corners.reshape(-1, 3)[first]
        self.cells = cells.reshape(self.blocks.shape)
        self.size = float(np.linalg.norm(self.points.max(axis=0) - self.points.min(axis=0)))
        self.vertex_normals = _unit(pseudo_normals(self.points, self.cells, facet_normals(corners))[0])
        self.rim = _rim(self.cells)
        self._k = min(CANDIDATES, len(self.cells))
        #: the reference facets' largest centroid-to-vertex distance
        self._rmax = float(np.max(np.linalg.norm(corners - corners.mean(axis=1, keepdims=True), axis=2)))
        #: the reach of the next projection (0: found by the first one's check)
        self.reach = 0.0
        #: the facets sent to this rank and the rounds taken by the last :meth:`nearby` (a bench's numbers)
        self.received, self.rounds = 0, 0

    @staticmethod
    def _local(d: Any, facets: npt.NDArray[np.int32], fdim: int, nv: int) -> tuple[Array, Array, Array]:
        """(corners (nf, nv, 3) outward-ordered, the global blocks (nf, nv) of W^h's nodes at them, their
        local blocks) of this rank's facets. A corner's node is found among the facet's closure dofs in its cell (the element's
        dof layout) by its coordinates, so that a curved (P2-geometry) facet is taken as a straight one."""
        msh, W = d.problem.mesh, d.W
        tdim = msh.topology.dim
        if not facets.size:
            return np.zeros((0, nv, 3)), np.zeros((0, nv), dtype=np.int64), np.zeros((0, nv), dtype=np.int64)
        msh.topology.create_connectivity(fdim, 0)
        msh.topology.create_connectivity(tdim, fdim)
        verts = msh.topology.connectivity(fdim, 0).array.reshape(-1, nv)[facets]
        corners = vertex_coordinates(msh, verts.reshape(-1)).T.reshape(-1, nv, 3).copy()
        f2c = msh.topology.connectivity(fdim, tdim)
        cells = f2c.array[f2c.offsets[facets]]
        x = msh.geometry.x
        inward = x[compat.mesh_geometry_dofmap(msh)[cells]].mean(axis=1) - corners.mean(axis=1)
        flip = np.einsum("ij,ij->i", facet_normals(corners), inward) > 0
        corners[flip, 0], corners[flip, 1] = corners[flip, 1].copy(), corners[flip, 0].copy()
        local = np.argmax(msh.topology.connectivity(tdim, fdim).array.reshape(-1, tdim + 1)[cells]
                          == facets[:, None], axis=1)
        layout = W.dofmap.dof_layout
        closure = np.array([layout.entity_closure_dofs(fdim, i) for i in range(tdim + 1)], dtype=np.int64)
        blocks = np.take_along_axis(compat.dofmap_list(W)[cells], closure[local], axis=1)      # (nf, nn)
        X = d._dof_x()[blocks]                                                                 # (nf, nn, 3)
        dist = np.linalg.norm(X[:, None, :, :] - corners[:, :, None, :], axis=3)            # (nf, nv, nn)
        which = np.argmin(dist, axis=2)
        size = np.linalg.norm(corners[:, 1] - corners[:, 0], axis=1)
        if np.any(np.take_along_axis(dist, which[..., None], axis=2)[..., 0] > 1e-8 * size[:, None]):
            raise DiscretisationError("W^h has no node at a master facet's vertex: not built")
        vblocks = np.take_along_axis(blocks, which, axis=1)
        glob = W.dofmap.index_map.local_to_global(vblocks.reshape(-1).astype(np.int32)).reshape(vblocks.shape)
        return corners, np.asarray(glob, dtype=np.int64), vblocks

    # ---------------------------------------------------------------- per state
    def displacements(self, u: Array) -> Array:
        """The master dofs' values (len(dofs),) of the owned array ``u`` of W^h, every one on every rank
        (collective: an allreduce of the whole surface's, the reference :meth:`nearby` is checked against)."""
        vals = np.zeros(len(self.dofs))
        vals[self._own] = u[self._local_dofs]
        self.comm.Allreduce(MPI.IN_PLACE, vals, op=MPI.SUM)
        return vals

    def owned_values(self, u: Array) -> Array:
        """The values of the owned array ``u`` of W^h at the master dofs this rank owns (not collective)."""
        return np.asarray(u[self._local_dofs])

    def nearby(self, u: Array, y: Array) -> tuple[Array, npt.NDArray[np.int64], Any]:
        """(the master dofs' values (len(dofs),), set at the facets received and 0 elsewhere; those facets;
        each point's :data:`CANDIDATES` facets of nearest centroids among them, (m, k) positions in that
        array, or None without points: :meth:`project`'s first guess, found by the reach's check) for
        projecting this rank's points y (m, 3) in the state ``u`` (the owned array of W^h): the deformed
        facets near them, sent by their owners (see the module; collective)."""
        comm = self.comm
        f = self._field.x.array
        f[:self._owned] = u[:self._owned]
        self._field.x.scatter_forward()
        mine_vals = f[self._mine_dofs]                                       # (n, nv, gdim)
        cur = self.points[self.cells[self._mine]]
        cur[..., :self.gdim] += mine_vals
        lo, hi = cur.min(axis=1), cur.max(axis=1)
        both = comm.allgather(((y.min(axis=0), y.max(axis=0)) if len(y) else None,
                               (lo.min(axis=0, initial=np.inf), hi.max(axis=0, initial=-np.inf))))
        boxes = [b for b, _ in both]
        surface = (np.min([m[0] for _, m in both], axis=0), np.max([m[1] for _, m in both], axis=0))
        slack = 1e-9 * self.size
        reach, rounds = self.reach, 0
        while True:
            rounds += 1
            send = []
            for box in boxes:
                if box is None:
                    send.append(np.zeros(0, dtype=np.int64))
                    continue
                meets = np.all((lo <= box[1] + reach) & (hi >= box[0] - reach), axis=1)
                send.append(np.flatnonzero(meets))
            got = comm.alltoall([(self._mine[sel], mine_vals[sel]) for sel in send])
            facets = np.concatenate([g[0] for g in got]).astype(np.int64)
            values = np.concatenate([g[1] for g in got]) if facets.size else np.zeros((0,) + mine_vals.shape[1:])
            need, cand = 0.0, None
            if len(y) and len(facets) >= self._k:      # the distance to each point's k-th nearest centroid
                pts = self.points[self.cells[facets]]
                pts[..., :self.gdim] += values
                dist, cand = cKDTree(pts.mean(axis=1)).query(y, k=self._k)
                need = float(np.max(dist.reshape(len(y), -1)[:, -1]))
            elif len(y):                # too few facets to tell: at least twice as far, and past the surface's box
                apart = np.maximum(np.maximum(surface[0] - y.max(axis=0), y.min(axis=0) - surface[1]), 0.0)
                need = max(2.0 * reach, float(np.linalg.norm(apart)) + 2.0 * self._rmax)
            need = comm.allreduce(need, op=MPI.MAX)
            if need <= reach:
                break
            reach = need * (1.0 + 1e-9) + slack
        self.reach = need * REACH_GROWTH + slack
        self.received, self.rounds = len(facets), rounds
        vals = np.zeros(len(self.dofs))
        vals[self.at[facets]] = values
        return vals, facets, None if cand is None else cand.reshape(len(y), self._k)

    def _closest(self, cur: Array, y: Array, cand: Any = None) -> tuple[Array, Array]:
        """(closest points (m, 3), facets (m,)) of the points y on the deformed facets ``cur``: the best of
        the :data:`CANDIDATES` facets of nearest centroids, then, for the points within :data:`NEAR` sizes
        of that facet (its largest centroid-to-vertex distance r), every facet that can do better: its
        centroid within the best distance + its own r (facets grouped by r within a factor 2, one KD-tree
        query per group, so that a refined contact zone is not searched with the coarse facets' r). A
        farther point keeps the first answer, whose gap is an upper bound of the true one: such a point
        cannot reach the surface within a step."""
        centroids = cur.mean(axis=1)
        radii = np.max(np.linalg.norm(cur - centroids[:, None], axis=2), axis=1)
        k = min(CANDIDATES, len(cur))
        if cand is None:            # (given: the same query, made by nearby)
            cand = cKDTree(centroids).query(y, k=k)[1].reshape(len(y), k)
        q, element, dist = _best(y, np.repeat(np.arange(len(y)), k), cand.reshape(-1), cur)
        near = np.flatnonzero(dist <= NEAR * radii[element])
        if near.size:
            group = np.floor(np.log2(np.maximum(radii, 1e-300))).astype(np.int64)
            yn = y[near]
            point: list[Any] = [np.arange(len(near))]
            facet: list[Any] = [element[near]]
            for g in np.unique(group):
                members = np.flatnonzero(group == g)
                lists = cKDTree(centroids[members]).query_ball_point(yn, dist[near] + radii[members].max())
                point.append(np.repeat(np.arange(len(near)), [len(ell) for ell in lists]))
                facet.append(members[np.fromiter((e for ell in lists for e in ell), dtype=np.int64,
                                                 count=int(sum(len(ell) for ell in lists)))])
            q[near], element[near], _ = _best(yn, np.concatenate(point), np.concatenate(facet), cur)
        return q, element

    def project(self, y: Array, vals: Array, facets: npt.NDArray[np.int64] | None = None,
                candidates: Any = None) -> tuple[Array, Array, Array, Array]:
        """For the points y (m, 3), with the master dofs' values ``vals``: (signed distances phi (m,), unit
        normals n (m, 3), the closest facets (m,), the barycentric coordinates xi (m, nv) of the closest
        points: the master vertices' weights) on the deformed surface (see the module), among ``facets``
        (default: every facet; ``candidates``: each point's facets of nearest centroids among them, as
        :meth:`nearby` gives them)."""
        if len(y) == 0:
            return np.zeros(0), np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros((0, self.cells.shape[1]))
        among = np.arange(len(self.cells)) if facets is None else np.asarray(facets, dtype=np.int64)
        if not len(among):
            raise DiscretisationError("no master facet received for a slave point (internal error)")
        cur = self.points[self.cells[among]]
        cur[..., :self.gdim] += vals[self.at[among]]
        q, local = self._closest(cur, y, candidates)
        element = among[local]
        xi = np.clip(barycentric(q, cur[local]), 0.0, 1.0)
        xi /= xi.sum(axis=1, keepdims=True)
        n = _unit(np.einsum("nv,nvk->nk", xi, self.vertex_normals[self.cells[element]]))
        r = y - q
        phi = np.einsum("ij,ij->i", r, n)
        # beyond the surface's rim (its closest point on the open boundary, the point off to the side): no
        # contact with this surface, not an imaginary plane through the rim (no row: n = 0, its distance)
        on_rim = np.any((xi < 1e-12) & self.rim[element], axis=1) if xi.shape[1] == 3 else \
            np.any((xi > 1.0 - 1e-12) & self.rim[element][:, ::-1], axis=1)
        lateral = np.linalg.norm(r - phi[:, None] * n, axis=1)
        size = np.linalg.norm(cur[local, 1] - cur[local, 0], axis=1)
        off = on_rim & (lateral > RIM * size)
        n[off], phi[off] = 0.0, np.linalg.norm(r[off], axis=1)
        return phi, n, element, xi
