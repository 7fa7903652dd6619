"""Friction against an obstacle whose normal turns from node to node and step to step (a curved or
tilted obstacle): the node frames of :class:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton`
with ``frames=True``.

Each contact node's unknowns are its Cartesian components in an orthonormal frame Q_i (row 0 the
obstacle's normal n_i, then the tangents), given before every step by :meth:`NodeFrames.set_rows`
with the bounds of n_i . x_i; the frictional Newton then works on the frame's components as on the
axis-aligned dofs (:mod:`~sdm_dolfinx.solvers.friction_system`, "Frames"). The friction laws are
isotropic in the tangent plane, so the solution does not depend on the tangents' choice.
"""
from petsc4py import PETSc

import numpy as np
import scipy.sparse as sp

#: the bound of a row that holds nothing this step (rows between bodies: no master point)
UNBOUNDED = 1e30


def surface_matrix(ids, vals, n_columns, comm):
    """Every rank's rows ((k, m, w) ``vals`` on the global dofs ``ids`` (m, w): unknown j * m + i is row i
    along axis j) as one scipy CSR matrix on every rank, in rank order (the layout of
    :func:`~sdm_dolfinx.solvers.friction_rows.rows_matrix`)."""
    k, m, w = vals.shape
    mine = sp.csr_matrix((vals.reshape(-1), (np.repeat(np.arange(k * m), w), np.tile(ids.reshape(-1), k))),
                         shape=(k * m, n_columns))
    mine.sum_duplicates()
    mine.eliminate_zeros()
    return sp.vstack(comm.allgather(mine), format="csr")


def frames_of(normals):
    """(m, k, k) orthonormal frames whose first rows are the unit ``normals`` (m x k): in 2-D the
    tangent (n_y, -n_x) (e_x for n = e_y, as the axis-aligned bound's tangential dof); in 3-D t1 the
    axis of least |n_c| (the lowest such c) made orthogonal to n, t2 = n x t1 (a function of n alone: a
    restart rebuilds the same frames). Friction is isotropic: the solution does not depend on the
    tangents' choice, only the Newton iterations' start does."""
    n = np.asarray(normals, dtype=float)
    m, k = n.shape
    Q = np.zeros((m, k, k))
    Q[:, 0] = n
    if k == 2:
        Q[:, 1, 0], Q[:, 1, 1] = n[:, 1], -n[:, 0]
        return Q
    axis = np.zeros((m, 3))
    axis[np.arange(m), np.argmin(np.abs(n), axis=1)] = 1.0
    t1 = axis - np.einsum("ij,ij->i", axis, n)[:, None] * n
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    Q[:, 1], Q[:, 2] = t1, np.cross(n, t1)
    return Q


def at_component(Q, comp):
    """The frames Q (m, k, k; row 0 the normal) with their rows reordered so that the normal is row
    ``comp`` and the tangents fill the other rows in order."""
    out = np.empty_like(Q)
    out[:, comp] = Q[:, 0]
    for j, c in enumerate(c for c in range(Q.shape[1]) if c != comp):
        out[:, c] = Q[:, 1 + j]
    return out


def to_frame(a, dofs, Q):
    """a := T^T a in place, T the rotation of :func:`rotation`: a_i := Q_i a_i at the nodes whose owned
    local rows are ``dofs`` (m, k); ``a`` an owned array, a vector or one row of a matrix per dof.
    Returns ``a``."""
    if len(dofs):
        a[dofs] = np.einsum("ikc,ic...->ik...", Q, a[dofs])
    return a


def from_frame(a, dofs, Q):
    """a := T a in place (the inverse of :func:`to_frame`: a_i := Q_i^T a_i). Returns ``a``."""
    if len(dofs):
        a[dofs] = np.einsum("ikc,ik...->ic...", Q, a[dofs])
    return a


def rotation(A, dofs, Q, T=None):
    """The PETSc matrix T (A's layout) with U = T Y: U_i = Q_i^T Y_i at the nodes whose owned local dofs
    are ``dofs`` (m, k), the identity elsewhere; ``T`` (an earlier result for the same dofs) gets the new
    node blocks in place (every entry of a block is set: the block's pattern is dense)."""
    r0, nloc = A.getOwnershipRange()[0], A.getLocalSize()[0]
    if T is None:                                   # the identity off the nodes, once
        T = PETSc.Mat().createAIJ(A.getSizes(), nnz=Q.shape[1] if len(Q) else 1, comm=A.getComm())
        off = np.ones(nloc, dtype=bool)
        off[np.asarray(dofs).reshape(-1)] = False
        for i in np.flatnonzero(off):
            T.setValue(r0 + i, r0 + i, 1.0)
    for i in range(len(dofs)):                      # U_c = sum_k Q_kc Y_k at the node's dofs
        g = (r0 + np.asarray(dofs[i])).astype(PETSc.IntType)
        T.setValues(g, g, np.ascontiguousarray(Q[i].T, dtype=PETSc.ScalarType))
    T.assemble()
    return T


class NodeFrames:
    """The frames' side of :class:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton` (a mixin:
    it uses the solver's ``frames``, ``rowwise``, ``surface``, ``m``, ``ndofs``, ``tdofs``, ``lb`` and
    ``system``)."""

    #: rows between bodies: the last step's frames (m, k, k; row 0 the normal), None before it
    row_frames = None

    def set_rows(self, normals, lb):
        """Frames (see the class): the unit normals (m x k, Cartesian) and the lower bounds of
        n_i . x_i of the next step; the tangents are those of :func:`frames_of`. Rows between bodies
        (``surface``): ``normals`` is (ids (m, w) global dofs, values (k, m, w)): the normal rows, then the
        tangential ones (:meth:`~sdm_dolfinx.method.body_rows.BodyRows.rows`); a row of zeros holds nothing
        this step (no bound, no friction)."""
        if self.surface:
            ids, vals = normals
            k = vals.shape[0]
            self.system.set_matrix(surface_matrix(ids, vals, self.K.getSize()[1], self.comm))
            #: the rows' frames (m, k, k; row 0 the normal, zero where a row holds nothing)
            self.row_frames = np.ascontiguousarray(np.transpose(vals[:, :, :k], (1, 0, 2)))
            alive = np.any(self.row_frames[:, 0] != 0.0, axis=1)
            self.lb = np.where(alive, np.asarray(lb, dtype=float).reshape(self.m), -UNBOUNDED)
            if self._s_all is not None:          # Tresca: no threshold where nothing holds
                self.s = np.where(alive, self._s_all, 0.0)
            if self._sets is not None:          # a row that holds nothing starts free: not active, not stuck
                active, stick, sigma = self._sets
                self._sets = (active & alive, stick & alive, sigma)
            # nor does it carry a force into the Coulomb fixed point's thresholds or the 3-D linearisation
            self.lam = np.where(alive, self.lam, 0.0)
            self.lam_t = np.where(alive.reshape((-1,) + (1,) * (np.ndim(self.lam_t) - 1)), self.lam_t, 0.0)
            return
        k = 2 if self.tdofs.ndim == 1 else 1 + self.tdofs.shape[1]
        n = np.asarray(normals, dtype=float).reshape(self.m, k)
        self.system.set_frames(frames_of(n))
        self.lb = np.asarray(lb, dtype=float).reshape(self.m)

    def _components(self, u):
        """The values of the node's frame components of the owned array u at this rank's contact
        nodes: (normal (m,), tangential (m,) or (m, 2)); rows: the rows' values (collective)."""
        if self.rowwise:
            y = self.system.values(u)
        elif not self.frames:
            return u[self.ndofs], u[self.tdofs]
        else:
            y = self.system.rotate(np.asarray(u)[self.system.cdofs])
        m = self.m
        return y[:m], (y[m:] if self.tdofs.ndim == 1 else y[m:].reshape(2, m).T)

    def tangential(self, u):
        """The tangential components (the order of ``tdofs``) of the owned array ``u`` at this rank's
        contact nodes: the reference ``xref_t`` of :meth:`solve` and the slip's ends (a copy)."""
        return np.array(self._components(u)[1], dtype=float)

    def frame_tangential(self, vectors):
        """Frames: the tangential components (m, or m x 2, along each node's t, or t1 and t2) of the
        Cartesian vectors (m x k) at the nodes (an obstacle's own displacement there)."""
        y = np.einsum("ikc,ic->ik", self.system.Q, np.asarray(vectors, dtype=float))[:, 1:]
        return y[:, 0].copy() if self.tdofs.ndim == 1 else y

    def cartesian(self, tangential):
        """3-D frames: the tangential vectors (m x 2, along each node's t1, t2) as Cartesian ones (m x 3), also
        on rows between bodies; without frames, or in 2-D, ``tangential`` itself (before the first step's
        frames: zeros)."""
        tangential = np.asarray(tangential, dtype=float)
        if tangential.ndim == 1 or not (self.frames or self.surface):
            return tangential
        Q = self.system.Q if self.frames else self.row_frames
        if Q is None:
            return np.zeros((len(tangential), 3))
        return np.einsum("ik,ikc->ic", tangential, Q[:, 1:, :])

    def imposed_gap(self, x):
        """min over this rank's contact nodes of x_n - lb (in the frame; +inf without nodes)."""
        return float(np.min(self._components(x)[0] - self.lb, initial=np.inf))
