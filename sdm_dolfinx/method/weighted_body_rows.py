"""The weighted (mortar-type) gap between bodies: ``constrain="weighted"`` with ``contact_pairs``.

The node-to-surface rows of :mod:`.body_rows` hold the slave vertices only (eq. (13)), and a P2 slave
face sinks into the master between them (the mid-edge nodes: docs/contact.md). As for a rigid plane
(:mod:`.weighted_rows`), the weighted gap holds, at each slave vertex a_i, the gap averaged against the
slave boundary's P1 hat function psi_i:

    G_i X = sum_j w_ij r_j(X) >= sum_j w_ij g_j,   w_ij = int_S psi_i phi_j ds / int_S psi_i ds,

S the pairs' slave facets, j over the nodes of W^h on S (vertices and P2 mid-edge nodes) and phi_j their
(scalar) basis functions, r_j X >= g_j the node-to-surface row of node j (:meth:`.body_rows.BodyRows.
node_rows`: its normal n_j, its closest point on the deformed master, the master held at the vertices of
that facet): the gap's W^h interpolant on the slave face, weighted by psi_i. sum_j w_ij = 1, so the row
is an average and its multiplier a nodal force, as the vertex rows' (the columns keep their meaning).

**What it keeps.** Each r_j is equal and opposite on the two bodies (its slave entries n_j, its master
entries -xi_v n_j, sum_v xi_v = 1), so is every G_i: the contact conserves the total momentum exactly.
A gap that is linear along the slave face meets every row exactly where it meets the nodes' rows (a flat
face pressed flat onto a flat master face: the contact patch test). A node j whose point has no master
point (beyond the master's rim: its node-to-surface row is zero) is left out of the rows it enters, the
others' weights renormalised; a row none of whose nodes has one holds nothing this step. Dirichlet data on
the slave faces' nodes: refused in one line (the vertex rows drop such a vertex).

**Columns.** ``gap_imposed`` (``min_gap_imposed``) is the rows' value at the constrained iterate: here the
weighted (averaged) gap, as with the rigid plane's weighted rows; ``gap_min_boundary`` stays the nodes'
own distances. A row's multiplier is credited to the pair of its largest weight (``contact_force_<pair>``):
exact where the pairs' slave faces do not share a vertex (every demo); a vertex whose hat function spans
two pairs' slave facets mixes their gaps in one row (not refused, not tested).

**Parallel.** A node's row is built by the rank that owns the node (as the time series' boundary gaps),
the weights w_ij are the columns of the assembled boundary matrix int psi_i phi_j ds that this rank owns
(its transpose: the rows a node enters), and each node sends w_ij r_j to the owner of vertex a_i (one
alltoall per step of the nodes' rows, width (1 + nv) gdim). The rows read every node of the slave faces
(the step solver caches K^-1 at them: :class:`~sdm_dolfinx.solvers.gap_rows.SurfaceRows`).

**Friction.** The tangential rows of G_i are the same weights on the tangents of the frame of row i's
normal (sum_j w_ij n_j, normalised): the slip is the weighted average of the nodes' relative tangential
motions, along one frame per row.
"""
from __future__ import annotations

from typing import Any

from mpi4py import MPI

import numpy as np
import ufl

from sdm_dolfinx import compat
from sdm_dolfinx.method.body_rows import BodyRows, tangential_rows
from sdm_dolfinx.method.contact_boundary import contact_measure
from sdm_dolfinx.method.dofs import where_least
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.problems.base import label
from sdm_dolfinx.problems.contact_pairs import slave_facets

#: the quadrature degree of int psi_i phi_j ds (degree 3 for P2 on straight facets), as :mod:`.weighted_rows`
QUADRATURE_DEGREE = 4


class WeightedBodyRows(BodyRows):
    """The weighted gap rows between the bodies of a Discretisation ``d`` (see the module): the rows of
    :class:`~.body_rows.BodyRows` (one per slave vertex, ``d.cdofs``'s order) averaged over the slave face."""

    def __init__(self, d: Any) -> None:
        super().__init__(d)
        p, W, msh = d.problem, d.W, d.problem.mesh
        bs = W.dofmap.index_map_bs
        if msh.topology.dim == 1:
            raise DiscretisationError(f"{label(p)}: constrain='weighted' is constrain='vertices' in 1-D (a contact "
                                      f"face is a point); use constrain='vertices'")
        # the nodes of the slave faces (owned): each once, held by every pair whose slave facets it is on
        blocks = np.unique(np.concatenate([dofs[:, 0] // bs for dofs, _ in self._bnodes]))
        self._ndofs = blocks[:, None] * bs + np.arange(self.gdim)
        self._nx = d._dof_x()[blocks].T.copy()
        self._nmember = np.array([np.isin(blocks, dofs[:, 0] // bs) for dofs, _ in self._bnodes])
        # w_ij: int_S psi_i phi_j ds, transposed (its rows: the W^h dofs, owned as the nodes are)
        ds = contact_measure(d, slave_facets(p.contact_pairs, msh), QUADRATURE_DEGREE)
        q, u = ufl.TestFunction(d.Q1), ufl.TrialFunction(W)
        full = compat.assemble_matrix(d.form(q * u[0] * ds))
        transposed = full.transpose()
        indptr, cols, vals = transposed.getValuesCSR()
        full.destroy(), transposed.destroy()
        start, count = indptr[blocks * bs], np.diff(indptr)[blocks * bs]
        take = np.repeat(start - (np.cumsum(count) - count), count) + np.arange(count.sum())
        node, vertex, w = np.repeat(np.arange(len(blocks)), count), cols[take], vals[take]
        #: (node position, global Q1 vertex, w) of every (i, j) with w_ij != 0 this rank's nodes enter
        self._entries = (node[w != 0.0], np.asarray(vertex[w != 0.0], dtype=np.int64), np.asarray(w[w != 0.0]))
        ranges = np.array(self.comm.allgather(d.Q1.dofmap.index_map.local_range), dtype=np.int64)
        self._owner = np.searchsorted(ranges[:, 1], self._entries[1], side="right")
        q1_lo = d.Q1.dofmap.index_map.local_range[0]
        self._row_of = np.full(d.Q1.dofmap.index_map.size_local, -1, dtype=np.int64)   # owned Q1 dof -> row
        owned = np.asarray(d.q1_of_c) < len(self._row_of)
        self._row_of[np.asarray(d.q1_of_c)[owned]] = np.flatnonzero(owned)
        self._q1_lo = q1_lo
        stray = self.comm.allreduce(int(np.count_nonzero(~owned)), op=MPI.SUM)
        if stray:
            raise DiscretisationError(f"{label(p)}: constrain='weighted': {stray} slave vertices' P1 dofs are owned by "
                                      f"another rank than their W^h dofs (internal error); use constrain='vertices'")
        fixed = self.comm.allreduce(int(np.count_nonzero(np.isin(self._ndofs, np.asarray(d.ddofs, dtype=np.int64)))),
                                    op=MPI.SUM)
        if fixed:           # their rows would read Dirichlet dofs as unknowns
            raise DiscretisationError(f"{label(p)}: constrain='weighted': {fixed} components of the slave faces' nodes "
                                      f"carry Dirichlet data (dirichlet_facets), which the weighted gap between bodies "
                                      f"does not take yet: use constrain='vertices'")
        self.read = np.unique(np.concatenate([self.read, *self.comm.allgather(self._ndofs.reshape(-1) + self._lo)]))

    def phi(self, u: Any, t: float = 0.0, boundary: bool = False) -> Any:
        """As :meth:`.body_rows.BodyRows.phi`; ``boundary``: every node of the slave faces once, against every
        pair it is on (the rows' own projection, key "nodes": the time series' boundary gaps of U^{n+1} are the
        next step's rows' projection, made once). Its minimum and where it is are the per-pair nodes' ones."""
        if not boundary:
            return super().phi(u, t)
        return self._closest(u, self._nx, self._ndofs, self._nmember, key="nodes")[0]

    def where(self, u: Any, t: float = 0.0) -> Any:
        """The reference coordinates (gdim,) of the slave faces' node nearest to its master surface."""
        return where_least(self.comm, self.phi(u, t, boundary=True), self._nx)[:self.gdim]

    def rows(self, u: Any, t0: float, t1: float, weight: float,
             tangential: bool = False) -> tuple[tuple[Any, Any], Any]:
        """The weighted rows (the format of :meth:`.body_rows.BodyRows.rows`; collective)."""
        ids, vals, g, pair, wts, normals = self.node_rows(u, self._nx, self._ndofs, self._nmember, "nodes")
        node, vertex, w = self._entries
        # a node without a master point (no pair's, or beyond the master's rim: a zero normal) enters no row
        live = np.isfinite(g[node]) & np.any(normals[node] != 0.0, axis=1)
        node, vertex, w, owner = node[live], vertex[live], w[live], self._owner[live]
        k, gd = ids.shape[1], self.gdim
        send = []
        for r in range(self.comm.size):
            at = owner == r
            j = node[at]
            send.append((vertex[at], w[at], ids[j], vals[j], wts[j], g[j], normals[j], pair[j]))
        got = self.comm.alltoall(send)
        vertex, w, nid, nval, nwts, ng, nn, npair = (np.concatenate([x[i] for x in got]) for i in range(8))
        m = len(self.dofs)
        row = self._row_of[vertex - self._q1_lo] if len(vertex) else np.zeros(0, dtype=np.int64)
        if np.any(row < 0):
            raise DiscretisationError("a slave node's weight reached a vertex that is not a slave vertex (internal "
                                      "error)")
        total = np.bincount(row, weights=w, minlength=m)
        share = w / np.where(total > 0, total, 1.0)[row]
        rhs = np.where(total > 0, np.bincount(row, weights=share * ng, minlength=m), -np.inf)
        normal = np.zeros((m, gd))
        np.add.at(normal, row, share[:, None] * nn)
        normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
        self.pair_of_row[:] = -1
        best = np.lexsort((-w, row))                              # each row's largest weight first
        first = best[np.r_[True, row[best][1:] != row[best][:-1]]] if len(row) else best
        self.pair_of_row[row[first]] = npair[first]
        # the entries (row, column) summed: (m, width) padded with the row's first slave dof at 0
        r_e, c_e, base = np.repeat(row, k), nid.reshape(-1), int(self.read.max(initial=0)) + 1
        key, inv = np.unique(r_e * base + c_e, return_inverse=True)
        v_e = np.bincount(inv, weights=np.repeat(share, k) * nval.reshape(-1), minlength=len(key))
        t_e = np.bincount(inv, weights=np.repeat(share, k) * nwts.reshape(-1), minlength=len(key))
        r_k, c_k = key // base, key % base
        count = np.bincount(r_k, minlength=m)
        width = self.comm.allreduce(int(count.max(initial=1)), op=MPI.MAX)
        pos = np.arange(len(key)) - np.repeat(np.cumsum(count) - count, count)
        out_ids = np.repeat(self.dofs[:, :1] + self._lo, width, axis=1)
        out_vals, out_wts = np.zeros((m, width)), np.zeros((m, width))
        out_ids[r_k, pos], out_vals[r_k, pos], out_wts[r_k, pos] = c_k, v_e, t_e
        if not tangential:
            return (out_ids, out_vals), rhs
        return (out_ids, tangential_rows(out_vals, out_wts, normal, out_ids % gd)), rhs
