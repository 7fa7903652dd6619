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
(level 1, P2/P1, stopped at step 105 in contact) by 7.3e-13. With it: 0. So the batches of
columns are recorded (by their constraints' coordinates, which any partition can map back) and
replayed, in order, on restart; the linear-iteration counters are restored too.

This reads the solver's internals (``solver.schur``, its ``fac`` and ``_ensure_columns``):
a step solver without them has no such history to restore.
"""
from mpi4py import MPI

import numpy as np


class SolverHistory:
    """Records the Schur column batches of ``integ``'s step solver from now on."""

    def __init__(self, integ):
        self.integ = integ
        solver = integ.solver
        self.schur = getattr(solver, "schur", None)
        self.batches = []
        if self.schur is None or not hasattr(self.schur, "_ensure_columns"):
            self.schur = None
            return
        fac = self.schur.fac
        solve_columns = fac.solve_columns

        def recorded(gcols, *args, **kwargs):       # every cached column comes through here
            self.batches.append(np.asarray(gcols, dtype=np.int64).copy())
            return solve_columns(gcols, *args, **kwargs)
        fac.solve_columns = recorded

    def _counters(self):
        solver = self.integ.solver
        return {name: getattr(solver, name) for name in ("schur", "inactive")
                if getattr(getattr(solver, name, None), "its", None) is not None}

    def capture(self):
        """Arrays for the checkpoint (collective): ``columns_x`` (coordinates of each cached
        column's constraint, in computing order), ``columns_batch`` (its batch number) and
        ``linear_its`` (the counters)."""
        its = {k: int(v.its) for k, v in self._counters().items()}
        out = {"linear_its_names": np.array(list(its), dtype=str), "linear_its": np.array(list(its.values()))}
        if self.schur is None or not self.batches:
            return {**out, "columns_x": np.zeros((0, 3)), "columns_batch": np.zeros(0, dtype=np.int64)}
        gids = np.concatenate(self.batches)
        batch = np.concatenate([np.full(len(b), i) for i, b in enumerate(self.batches)])
        gc = self.schur.gc
        cx = self.integ.discretisation.cx
        x = np.zeros((len(gids), 3))
        pos = {int(g): i for i, g in enumerate(gc)}
        for k, g in enumerate(gids.tolist()):
            i = pos.get(g)
            if i is not None:
                x[k] = cx[:, i]
        comm = self.integ.discretisation.comm
        xs = np.empty_like(x)
        comm.Allreduce(x, xs, op=MPI.SUM)               # each column's constraint is owned once
        x = xs
        return {**out, "columns_x": x, "columns_batch": batch.astype(np.int64)}

    def restore(self, data):
        """Replay the checkpoint's column batches and set the counters (collective)."""
        comm = self.integ.discretisation.comm
        x, batch = data.get("columns_x"), data.get("columns_batch")
        if self.schur is not None and x is not None and len(x):
            cx = self.integ.discretisation.cx
            gids = np.full(len(x), -1, dtype=np.int64)
            if cx.shape[1]:
                from scipy.spatial import cKDTree
                scale = max(float(np.abs(x).max()), 1.0)
                d, idx = cKDTree(cx.T).query(x)
                hit = d <= 1e-9 * scale
                gids[hit] = self.schur.gc[idx[hit]]
            found = np.empty_like(gids)
            comm.Allreduce(gids, found, op=MPI.MAX)
            gids = found
            if np.all(gids >= 0):                        # else: not this mesh (checked before)
                for b in range(int(batch.max()) + 1):
                    self.schur._ensure_columns(gids[batch == b].tolist())
        names = data.get("linear_its_names")
        if names is not None:
            counters = self._counters()
            for name, its in zip(names.tolist(), data["linear_its"].tolist()):
                if name in counters:
                    counters[name].its = int(its)
