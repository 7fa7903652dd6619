"""Gap rows between deformable bodies: the slave vertices of a Problem's ``contact_pairs`` stay
outside the master surfaces (node-to-surface), frictionless or, with the run option ``friction``, with
tangential rows of the same weights along the tangents of n (:meth:`BodyRows.rows`: the slip is the
relative tangential motion, :mod:`sdm_dolfinx.contact.friction`).

**The row.** At the start of a step from (U^n, t_n), a slave vertex a_i at y_i = a_i + U^n_i has its
closest point q on the deformed master surface (:mod:`.master_surface`: the chords of its facets), in
the facet F, with barycentric coordinates xi, the master's normal n there (its vertices' pseudo-normals
interpolated, reference configuration) and the gap phi_i = n . (y_i - q). The scheme's constrained
iterate X (midpoint U^{n+1/2}, backward Euler U^{n+1}) is held by the row linearised there, exactly as
a node against a rigid obstacle (:mod:`.obstacle_rows`) but with the obstacle's own displacement an
unknown:

    n . (X_i - sum_v xi_v X_v)  >=  n . (U^n_i - sum_v xi_v U^n_v) - phi_i,

v over the vertices of F (the master is held at its vertices as the slave is: :mod:`.master_surface`
says why, measured). The force it transmits, G^T lam, is lam_i n on the slave vertex and
-lam_i xi_v n on the master's: equal and opposite (sum_v xi_v = 1), so the contact conserves the total
momentum exactly, and its power lam_i n . (V_i - sum_v xi_v V_v) is that of the relative normal
velocity, which the midpoint scheme's persistency makes vanish in sustained contact (the energy
balance of the obstacle rows, now between two moving surfaces). The rows are recomputed before every
step (projection, facet, weights); the step solver caches K^-1 columns per dof
(:class:`~sdm_dolfinx.solvers.gap_rows.SurfaceRows`), so a row that moves to another facet costs no
new solve once its dofs have been read.

**Mirror symmetry.** Two identical bodies meeting head on at +-v on meshes mirrored about the plane
between them, with flat contact faces (a plane bar with Poisson's ratio 0): each slave vertex projects
onto its mirror image, n is the face's normal, the row reads 2 n . X_i >= 2 n . U^n_i - 2 d_i (d_i its
distance to the plane of symmetry), the row of one body against a rigid plane there, and the
multiplier is the same: the two runs agree to the solver's tolerance (tests/physics/test_two_bodies.py).
On curved faces (two discs) the master's normal at a vertex is the mean of its two facets' and the runs
differ by the discretisation's O(h) (measured there).

**Dirichlet dofs** on a master facet (``dirichlet_facets``, constant data): their columns leave the
row and their (constant) values the right-hand side; a Dirichlet part on a contact surface is refused.

**Gaps.** The time series' gaps are the true signed distances phi of U at the state (not linearised):
``gap_min`` at the slave vertices, ``gap_min_boundary`` at every node of W^h on the slave facets.
"""
from __future__ import annotations

from typing import Any, Optional

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
from dolfinx import fem

from sdm_dolfinx.method.contact_boundary import vertex_flag
from sdm_dolfinx.method.dofs import vertex_to_dof
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.method.dofs import where_least
from sdm_dolfinx.method.master_surface import MasterSurface
from sdm_dolfinx.problems.base import label
from sdm_dolfinx.problems.contact_pairs import slave_vertices
from sdm_dolfinx.solvers.friction_frames import frames_of

Array = npt.NDArray[np.float64]


def refusal(integ: Any, scheme: Any, vi_solver: str, linear: str) -> Optional[str]:
    """The one-line refusal of what the rows between bodies do not take yet, or None (also without them)."""
    d = integ.discretisation
    if getattr(d, "body_rows", None) is None:
        return None
    what = f"problem {d.problem.name!r} has contact pairs"
    if scheme.bound_weight is None:
        return f"{what}, which scheme {scheme.name!r} does not take: use the midpoint or backward-euler scheme"
    if integ.block:
        return f"{what}, which mass 'consistent' (the (U, V) block system) does not take yet: use mass 'lumped'"
    if integ.contact != "exact":
        return f"{what}, which contact {integ.contact!r} does not take yet: use contact 'exact'"
    if vi_solver != "ssn" or linear not in ("auto", "schur"):
        return (f"{what}: their gap rows are solved by the semi-smooth Newton with linear strategy schur only (got "
                f"vi_solver {vi_solver!r}, linear {linear!r})")
    return None


def tangential_rows(vals: Array, weights: Array, normals: Array, comp: Any) -> Array:
    """(1 + gdim - 1, m, k): the normal rows ``vals`` (m, k), then the rows of the entries' ``weights`` along each
    tangent of the frame :func:`~sdm_dolfinx.solvers.friction_frames.frames_of` builds on ``normals`` (m, gdim;
    a zero normal: zero rows); ``comp`` (m, k): each entry's component."""
    Q = frames_of(normals) * np.any(normals != 0.0, axis=1)[:, None, None]   # (m, g, g), row 0 n
    comp = np.broadcast_to(comp, vals.shape)
    return np.stack([vals, *(weights * np.take_along_axis(Q[:, j], comp, axis=1)
                             for j in range(1, normals.shape[1]))])


class BodyRows:
    """The gap rows of a Discretisation ``d`` whose Problem declares ``contact_pairs`` (see the module).

    Attributes:
        dofs: (m, gdim) owned local dofs of W^h of this rank's slave vertices (``d.cdofs``'s order).
        x: (3, m) their reference coordinates.
        surfaces: the pairs' :class:`~.master_surface.MasterSurface`.
        read: the global dofs any row may read (every rank's slave dofs and every master dof; sorted).
    """

    def __init__(self, d: Any) -> None:
        p, W = d.problem, d.W
        self.comm, self.gdim, bs = d.comm, int(p.shape[0]), W.dofmap.index_map_bs
        msh = p.mesh
        c = p.constraint_component or 0
        self.dofs = ((np.asarray(d.cdofs, dtype=np.int64) - c) // bs)[:, None] * bs + np.arange(self.gdim)
        self.x = np.asarray(d.cx, dtype=float)
        lo = W.dofmap.index_map.local_range[0] * bs
        self.surfaces = [MasterSurface(d, pair.master, pair.name) for pair in p.contact_pairs]
        # which pairs hold each slave vertex: flagged on Q1 and summed into the owners (a vertex's owner need
        # not hold any of its slave facets)
        q1 = vertex_to_dof(d.Q1, d.cverts)
        self._member = np.array([vertex_flag(d, slave_vertices([pair], msh))[q1] > 0 for pair in p.contact_pairs])
        for k, pair in enumerate(p.contact_pairs):       # no slave vertex: no contact at all, silently
            if not self.comm.allreduce(int(np.count_nonzero(self._member[k])), op=MPI.SUM):
                raise DiscretisationError(f"{label(p)}: contact pair {pair.name!r}: slave names no exterior facet "
                                          f"on any rank (check the facets it selects)")
        blocks = (self.dofs[:, 0] + W.dofmap.index_map.local_range[0] * bs) // bs
        for k, (pair, s) in enumerate(zip(p.contact_pairs, self.surfaces)):
            own = self.comm.allreduce(int(np.count_nonzero(np.isin(blocks[self._member[k]], s.blocks))), op=MPI.SUM)
            if own:
                raise DiscretisationError(f"{label(p)}: contact pair {pair.name!r}: {own} slave vertices are on its "
                                          f"master surface too (a body's own facets, or faces that coincide): the "
                                          f"slave and master facets must belong to different bodies")
        bare = self.comm.allreduce(int(np.count_nonzero(np.asarray(d.cmeasure) <= 0.0)), op=MPI.SUM)
        if bare:                # its stresses (lambda_probe, contact_stress) would divide by 0
            raise DiscretisationError(f"{label(p)}: constraint_measure gives {bare} slave vertices no measure: it "
                                      f"should integrate over the contact pairs' slave facets (q * ds(slave tag))")
        lost = self.comm.allreduce(int(np.count_nonzero(~self._member.any(axis=0))), op=MPI.SUM)
        if lost:
            raise DiscretisationError(f"{label(p)}: {lost} constrained vertices belong to no contact pair's slave "
                                      f"facets (internal error)")
        # every node of W^h on each pair's slave facets (owned): gap_min_boundary
        self._bnodes = []
        for pair in p.contact_pairs:
            blocks = fem.locate_dofs_topological(W, msh.topology.dim - 1, np.asarray(pair.slave(msh), dtype=np.int32))
            blocks = blocks[blocks < W.dofmap.index_map.size_local]
            self._bnodes.append((blocks[:, None] * bs + np.arange(self.gdim), d._dof_x()[blocks].T.copy()))
        fixed = np.asarray(d.ddofs, dtype=np.int64) + lo
        self._free = []
        for s in self.surfaces:                     # a master dof with Dirichlet data: not in the rows
            hit = np.isin(s.dofs, fixed).astype(np.int32)
            self.comm.Allreduce(MPI.IN_PLACE, hit, op=MPI.MAX)
            self._free.append(hit == 0)
        moving = np.concatenate([np.asarray(k, dtype=np.int64) for k in d.part_dofs]) + lo if d.part_dofs else \
            np.zeros(0, dtype=np.int64)
        moving_all = np.concatenate(self.comm.allgather(moving))
        n = self.comm.allreduce(int(np.count_nonzero(np.isin(self.dofs + lo, moving))), op=MPI.SUM) + sum(
            int(np.count_nonzero(np.isin(s.dofs, moving_all))) for s in self.surfaces)
        if n:
            raise DiscretisationError(f"{label(p)}: a Dirichlet part prescribes {n} components of the contact "
                                      f"surfaces' nodes: leave the contact surfaces out of the parts")
        self._lo = lo
        self.read = np.unique(np.concatenate([np.concatenate(self.comm.allgather(self.dofs.reshape(-1) + lo))]
                                             + [s.dofs for s in self.surfaces]))
        x = np.asarray(msh.geometry.x)
        ext = np.concatenate([-np.min(x, axis=0, initial=np.inf), np.max(x, axis=0, initial=-np.inf)])
        self.comm.Allreduce(MPI.IN_PLACE, ext, op=MPI.MAX)
        #: the mesh's largest extent along an axis: the scale of the initial state's gap tolerance
        self.size = max(float(np.max(ext[3:] + ext[:3])), 1e-300)
        self._kept: dict[Any, Any] = {}
        #: which pair held each row in the last :meth:`rows` (-1: none)
        self.pair_of_row = np.full(len(self.dofs), -1, dtype=np.int64)

    # ---------------------------------------------------------------- projections
    def _closest(self, u: Array, x: Array, dofs: Array, member: Any, key: Any = None) -> tuple[Array, list[Any]]:
        """(phi (n,), per pair (which points, normals, facets, barycentric weights, master values)) of the points
        at reference ``x`` (3, n) with dofs ``dofs`` (n, gdim) in the state ``u`` (collective). With ``key``, the
        answer for the same points and the same values of u there and on the master surfaces is kept: a
        step's rows, its gap and the time series' gaps project the same state (decided on every rank)."""
        owned = [s.owned_values(u) for s in self.surfaces]      # every rank's part: the state on the surfaces
        mine = np.array(u[dofs]) if len(dofs) else np.zeros((0, self.gdim))
        kept = self._kept.get(key) if key is not None else None
        same = kept is not None and np.array_equal(kept[0], mine) and all(
            np.array_equal(a, b) for a, b in zip(kept[1], owned))
        if self.comm.allreduce(bool(same) if key is not None else False, op=MPI.LAND):
            assert kept is not None
            return kept[2]
        y = np.array(x.T, dtype=float, copy=True)
        if len(dofs):
            y[:, :self.gdim] += mine
        phi, best, found = np.full(len(y), np.inf), np.full(len(y), -1), []
        for k, s in enumerate(self.surfaces):
            sel = np.flatnonzero(member[k])
            vals, near, cand = s.nearby(u, y[sel])             # collective: every rank, every pair
            ph, n, el, xi = s.project(y[sel], vals, near, cand)
            closer = ph < phi[sel]
            phi[sel[closer]], best[sel[closer]] = ph[closer], k
            found.append((sel, n, el, xi, vals))
        out = phi, [(sel[best[sel] == k], *(a[best[sel] == k] for a in (n, el, xi)), v)
                    for k, (sel, n, el, xi, v) in enumerate(found)]
        if key is not None:
            self._kept[key] = (mine, owned, out)
        return out

    def phi(self, u: Array, t: float = 0.0, boundary: bool = False) -> Array:
        """The signed distances (local) of the slave vertices (``boundary``: of every node of the slave
        facets) to their master surfaces in the state ``u`` (collective)."""
        if not boundary:
            return self._closest(u, self.x, self.dofs, self._member, key="vertices")[0]
        out = []
        for k, (dofs, x) in enumerate(self._bnodes):
            member = np.zeros((len(self.surfaces), len(dofs)), dtype=bool)
            member[k] = True
            out.append(self._closest(u, x, dofs, member, key=("boundary", k))[0])
        return np.concatenate(out) if out else np.zeros(0)

    def gap(self, u: Array, t: float = 0.0, boundary: bool = False) -> float:
        """min of :meth:`phi` over the ranks (+inf without nodes; collective)."""
        return self.comm.allreduce(float(np.min(self.phi(u, t, boundary), initial=np.inf)), op=MPI.MIN)

    def where(self, u: Array, t: float = 0.0) -> Array:
        """The reference coordinates (gdim,) of the slave facets' node nearest to its master surface."""
        bx = np.concatenate([x for _, x in self._bnodes], axis=1) if self._bnodes else np.zeros((3, 0))
        return where_least(self.comm, self.phi(u, t, boundary=True), bx)[:self.gdim]

    # ---------------------------------------------------------------- the step's rows
    def rows(self, u: Array, t0: float, t1: float, weight: float,
             tangential: bool = False) -> tuple[tuple[Any, Array], Array]:
        """((ids (m, k) global dofs, values), g (m,)) of the step linearised at ``u`` = U^n (see the module;
        collective). Values: (m, k), the normal rows; with ``tangential`` (friction between bodies)
        (1 + gdim - 1, m, k): the normal rows, then the same rows along each tangent of the frame
        :func:`~sdm_dolfinx.solvers.friction_frames.frames_of` builds on n (a row without a master point,
        zero: it holds nothing this step)."""
        ids, vals, g, pair, weights, normals = self.node_rows(u, self.x, self.dofs, self._member, "vertices")
        self.pair_of_row[:] = pair
        if not tangential:
            return (ids, vals), g
        return (ids, tangential_rows(vals, weights, normals, ids % self.gdim)), g

    def node_rows(self, u: Array, x: Array, dofs: Array, member: Any, key: Any) -> tuple[Any, ...]:
        """The node-to-surface rows of the points at reference ``x`` (3, n) with dofs ``dofs`` (n, gdim) held by
        the pairs ``member`` (pairs, n) in the state ``u`` (collective): ids (n, k) global dofs, values (n, k),
        g (n,), the pair of each (-1: none), the entries' weights (1 at the slave's, -xi_v at the master's) and
        the normals n (n, gdim). A point without a master point has a row of zeros and a zero normal: g -inf
        when no pair holds it, finite (minus its distance) when its closest point is beyond the rim."""
        phi, per_pair = self._closest(u, x, dofs, member, key=key)
        m, g = len(dofs), self.gdim
        width = g + max((s.at.shape[1] * g for s in self.surfaces), default=0)
        ids, vals = np.full((m, width), -1, dtype=np.int64), np.zeros((m, width))
        ids[:, :g] = dofs + self._lo
        rhs = np.zeros(m)
        pair = np.full(m, -1, dtype=np.int64)
        weights, normals = np.zeros((m, width)), np.zeros((m, g))
        for k, (sel, n, el, xi, mvals) in enumerate(per_pair):
            pair[sel] = k
            s, free = self.surfaces[k], self._free[k]
            at = s.at[el]                                                   # (p, nv, gdim) positions in s.dofs
            coef = -xi[:, :, None] * n[:, None, :g] * free[at]              # the master vertices' entries
            vals[sel, :g] = n[:, :g]
            w = at.shape[1] * g
            vals[sel, g:g + w] = coef.reshape(len(sel), w)
            ids[sel, g:g + w] = s.dofs[at].reshape(len(sel), w)
            rhs[sel] = np.einsum("ij,ij->i", n[:, :g], u[dofs[sel]]) + np.einsum("pak,pak->p", coef, mvals[at])
            normals[sel] = n[:, :g]
            weights[sel, :g] = 1.0
            weights[sel, g:g + w] = (-xi[:, :, None] * free[at]).reshape(len(sel), w)
        unread = ids < 0
        ids[unread], vals[unread] = dofs[:, :1].repeat(width, axis=1)[unread] + self._lo, 0.0
        return ids, vals, rhs - phi, pair, weights, normals

    def after_step(self, info: dict, u: Array, t1: float, lam: Array) -> None:
        """``info["gap_end"]``: the true signed distance of U^{n+1} = ``u`` (collective)."""
        info["gap_end"] = self.gap(u, t1)
