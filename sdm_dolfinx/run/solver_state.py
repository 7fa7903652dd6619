"""The step solver's state that a restart must restore for the continued run to be
bit-identical to an uninterrupted one (serially; see :mod:`.restart`).

Besides U, V and the active set (the first Newton iterate), the semi-smooth Newton's
``schur`` strategy carries one piece of history: its cache of columns K^-1 e_i
(:class:`~sdm_dolfinx.solvers.schur.SchurComplement`). Which columns are cached decides
whether a Newton system is solved by the dense Schur complement or by Krylov (the cache
is capped), and a column's last bits depend on the batch it was computed in (a
multiple-right-hand-side solve, MatMatSolve, rounds differently from a single one).
Measured (differences relative to each column's largest value) without the cache: the
membrane (N = 24, P1+/P0, dt = 1e-3, stopped at step 270 with 223 constraints active,
restarted) differs from step 275 on (where the active set drops below the Schur threshold)
by up to 3.9e-13 in the energy, 1.1e-12 in the kinetic energy, 8.8e-13 in u_probe; the disc
(level 1, P2/P1, dt = 1e-4, stopped at step 105 in contact) by 7.3e-13. With it: 0. So the
batches of columns are recorded (by their constraints' coordinates and components, which any
partition can map back) and replayed, in order, on restart; the linear-iteration counters are
restored too.

The frictional step solvers (:class:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton`,
2-D and 3-D) cache columns the same way (normal and tangential dofs) and keep more between
steps: the stick/slip sets and slip directions the next step starts from, the multipliers
(the 3-D linearisation and Coulomb's fixed point start from them) and a solve counter
(:meth:`~sdm_dolfinx.solvers.friction_newton.FrictionalNewton.state`). Measured without them
(the block of block_friction_*.toml and the ball's oblique impact at level 1, Coulomb and
Tresca, stopped sliding and sticking): the first step after the restart took 2-3 Newton
iterations instead of 1, and the continued runs differed by up to 1e-8 relative (the
elastic energy of the sticking block, the dissipated energy of the sticking ball). They are
stored per contact vertex, by its coordinates.

The gap-row Newton (:mod:`~sdm_dolfinx.solvers.gap_newton`: obstacles, the weighted gap) caches
columns of any dof of W^h (a weighted row reads the facets' dofs): its batches are recorded by
each dof's coordinates and component.

This reads the solver's internals (``solver.schur``, its ``fac`` and ``_ensure_columns``; ``solver.rows``;
the frictional solver's ``fac``, ``column_ids``, ``cache_columns``, ``state``): a step solver
without them has no such history to restore.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.io.checkpoint import CheckpointError
from sdm_dolfinx.mpiutil import gather_rows


def _nearest(saved_x, x):
    """Index into ``saved_x`` (k x 3) of each point of ``x`` (n x 3) and whether it is the same
    point (to 1e-9 of the coordinates' scale)."""
    if len(x) == 0 or len(saved_x) == 0:
        return np.zeros(len(x), dtype=np.int64), np.zeros(len(x), dtype=bool)
    from scipy.spatial import cKDTree
    scale = max(float(np.abs(saved_x).max()), 1.0)
    d, idx = cKDTree(saved_x).query(x)
    return idx, d <= 1e-9 * scale


class SolverHistory:
    """Records the cached-column batches of ``integ``'s step solver from now on; captures and
    restores the solver's state (frictional solvers: its sets and multipliers too)."""

    def __init__(self, integ):
        self.integ = integ
        solver = integ.solver
        self.batches = []
        self.friction = solver if hasattr(solver, "cache_columns") and hasattr(solver, "state") else None
        schur = getattr(solver, "schur", None)
        #: the gap-row Newton (obstacles, the weighted gap): its columns are any dofs of W^h, named by
        #: their dof's coordinates and component
        self.by_dof = hasattr(solver, "rows") and hasattr(solver.rows, "_ensure_columns")
        if self.by_dof:
            fac, self.gc = solver.fac, np.zeros(0, dtype=np.int64)
            self._ensure = lambda gids: solver.rows._ensure_columns([int(g) for g in gids])
        elif self.friction is not None:
            fac, self.gc = solver.fac, np.asarray(solver.column_ids, dtype=np.int64)
            self._ensure = solver.cache_columns
        elif schur is not None and hasattr(schur, "_ensure_columns"):
            fac, self.gc = schur.fac, np.asarray(schur.gc, dtype=np.int64)
            self._ensure = lambda gids: schur._ensure_columns(list(gids))
        else:
            self.gc = None
            return
        solve_columns = fac.solve_columns

        def recorded(gcols, *args, **kwargs):       # every cached column comes through here
            self.batches.append(np.asarray(gcols, dtype=np.int64).copy())
            return solve_columns(gcols, *args, **kwargs)
        fac.solve_columns = recorded

    @property
    def _cx(self):
        """(3, m) coordinates of this rank's constrained vertices (the solvers' order)."""
        return self.integ.discretisation.cx

    def _counters(self):
        solver = self.integ.solver
        return {name: getattr(solver, name) for name in ("schur", "inactive", "rows")
                if getattr(getattr(solver, name, None), "its", None) is not None}

    def _dofs(self):
        """(this rank's first global row, the owned dofs' coordinates (n, 3), the block size) of W^h."""
        d = self.integ.discretisation
        bs = d.W.dofmap.index_map_bs
        n = d.W.dofmap.index_map.size_local
        return d.W.dofmap.index_map.local_range[0] * bs, d._dof_x()[:n], bs

    def capture(self):
        """Arrays for the checkpoint (collective): ``columns_x`` (coordinates of each cached
        column's constraint, in computing order), ``columns_comp`` (its component: 0 normal, 1..
        tangential), ``columns_batch`` (its batch number), ``linear_its`` (the counters) and,
        for a frictional solver, ``friction_*`` (:meth:`_capture_friction`)."""
        its = {k: int(v.its) for k, v in self._counters().items()}
        out = {"linear_its_names": np.array(list(its), dtype=str), "linear_its": np.array(list(its.values())),
               **self._capture_columns()}
        if self.friction is not None:
            out.update(self._capture_friction())
        return out

    def _capture_columns(self):
        none = {"columns_x": np.zeros((0, 3)), "columns_comp": np.zeros(0, dtype=np.int64),
                "columns_batch": np.zeros(0, dtype=np.int64)}
        if self.gc is None or not self.batches:
            return none
        if self.by_dof:
            return self._capture_by_dof(none)
        gids = np.concatenate(self.batches)
        batch = np.concatenate([np.full(len(b), i) for i, b in enumerate(self.batches)])
        cx = self._cx
        m = cx.shape[1]
        x = np.zeros((len(gids), 3))
        comp = np.zeros(len(gids), dtype=np.int64)
        pos = {int(g): k for k, g in enumerate(self.gc)}
        for j, g in enumerate(gids.tolist()):
            k = pos.get(g)
            if k is not None:                           # column k: component k // m of vertex k % m
                x[j], comp[j] = cx[:, k % m], k // m
        comm = self.integ.discretisation.comm
        xs, cs = np.empty_like(x), np.empty_like(comp)
        comm.Allreduce(x, xs, op=MPI.SUM)               # each column's constraint is owned once
        comm.Allreduce(comp, cs, op=MPI.SUM)
        return {"columns_x": xs, "columns_comp": cs, "columns_batch": batch.astype(np.int64)}

    def _capture_by_dof(self, none):
        """The gap-row Newton's columns: each by its dof's coordinates and component (collective)."""
        gids = np.concatenate(self.batches)
        batch = np.concatenate([np.full(len(b), i) for i, b in enumerate(self.batches)])
        r0, xd, bs = self._dofs()
        local = gids - r0
        mine = (local >= 0) & (local < len(xd) * bs)
        x, comp = np.zeros((len(gids), 3)), np.zeros(len(gids), dtype=np.int64)
        x[mine], comp[mine] = xd[local[mine] // bs], local[mine] % bs
        comm = self.integ.discretisation.comm
        xs, cs = np.empty_like(x), np.empty_like(comp)
        comm.Allreduce(x, xs, op=MPI.SUM)               # each dof is owned once
        comm.Allreduce(comp, cs, op=MPI.SUM)
        return {"columns_x": xs, "columns_comp": cs, "columns_batch": batch.astype(np.int64)}

    def _capture_friction(self):
        """``friction_x`` (each contact vertex's coordinates), ``friction_<name>`` for each entry of
        the solver's :meth:`state` (one row per vertex), ``friction_started``, ``friction_starts``
        (gathered on rank 0, collective)."""
        comm = self.integ.discretisation.comm
        started, starts, per_vertex = self.friction.state()
        out = {"friction_x": gather_rows(self._cx.T.reshape(-1, 3), comm),
               "friction_started": np.array(bool(started)), "friction_starts": np.array(int(starts))}
        for name, values in per_vertex.items():
            out["friction_" + name] = gather_rows(values, comm)
        return out

    def restore(self, data):
        """Replay the checkpoint's column batches, set the counters and, for a frictional solver,
        its state (collective). A checkpoint without the frictional state (an older version's)
        leaves the solver to start its sets afresh.

        Raises:
            CheckpointError: the frictional state does not name this mesh's contact vertices.
        """
        self._restore_columns(data)
        names = data.get("linear_its_names")
        if names is not None:
            counters = self._counters()
            for name, its in zip(names.tolist(), data["linear_its"].tolist()):
                if name in counters:
                    counters[name].its = int(its)
        if self.friction is not None and "friction_x" in data:
            self._restore_friction(data)

    def _restore_columns(self, data):
        comm = self.integ.discretisation.comm
        x, batch = data.get("columns_x"), data.get("columns_batch")
        if self.gc is None or x is None or not len(x):
            return
        comp = data.get("columns_comp", np.zeros(len(x), dtype=np.int64))
        gids = np.full(len(x), -1, dtype=np.int64)
        if self.by_dof:                          # the dof of each saved column, on its owner
            r0, xd, bs = self._dofs()
            idx, hit = _nearest(xd, x)
            gids[hit] = r0 + idx[hit] * bs + comp[hit]
        else:
            cx = self._cx
            m = cx.shape[1]
            idx, hit = _nearest(cx.T, x)            # the vertex of each saved column, on its owner
            gids[hit] = self.gc[comp[hit] * m + idx[hit]]
        found = np.empty_like(gids)
        comm.Allreduce(gids, found, op=MPI.MAX)
        if np.all(found >= 0):                   # else: not this mesh (checked before)
            for b in range(int(batch.max()) + 1):
                self._ensure(found[batch == b])

    def _restore_friction(self, data):
        comm = self.integ.discretisation.comm
        idx, hit = _nearest(data["friction_x"], self._cx.T)
        if comm.allreduce(not np.all(hit), op=MPI.LOR):
            raise CheckpointError("the checkpoint's frictional state does not match this mesh's contact vertices")
        per_vertex = {name: data["friction_" + name][idx] for name in self.friction.STATE}
        self.friction.set_state(bool(data["friction_started"]), int(data["friction_starts"]), per_vertex)
