"""What a run returns (:class:`Result`) and the time series it records (:class:`TimeSeries`)."""
from dataclasses import dataclass, field

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.method.integrator import StepError

#: the columns of every run's time series; a Problem adds its ``extra_columns``
BASE_COLUMNS = ("step", "t", "energy", "kinetic", "potential", "u_probe", "lambda_probe", "n_active",
                "newton_its")


def num_steps(T, dt):
    """Number of steps of length dt in [0, T] (T rounded to a multiple of dt)."""
    return int(np.floor(T / dt + 1e-9))


class TimeSeries:
    """The scalar history of a run: one row per step (row 0 = the initial state).

    Every value is reduced over the ranks (identical on every rank).
    """

    def __init__(self, integ, problem, probe, cprobe, nsteps):
        self.integ, self.problem, self.probe, self.cprobe = integ, problem, probe, cprobe
        self.columns = BASE_COLUMNS + tuple(problem.extra_columns)
        self.data = {c: np.zeros(nsteps + 1) for c in self.columns}
        self.comm = problem.mesh.comm

    def record(self, n, t, U, V, lam, its, n_active):
        """Compute row ``n`` (time ``t``) from the state; returns it as a dict (with
        ``linear_its_total``, the cumulative linear iterations, for observers)."""
        integ, comm = self.integ, self.comm
        kin, pot = integ.energies(U, V)
        row = {"step": n, "t": t, "energy": kin + pot, "kinetic": kin, "potential": pot,
               "u_probe": self.probe(U), "lambda_probe": self.cprobe(lam), "n_active": n_active,
               "newton_its": its}
        if "contact_force" in self.columns:
            row["contact_force"] = comm.allreduce(float(np.sum(lam)), op=MPI.SUM)
        if "momentum_y" in self.columns:
            row["momentum_y"] = integ.momentum(V, self.problem.momentum_component)
        if "elastic" in self.columns:            # 1/2 U^T A U = potential + U^T L
            row["elastic"] = pot + U.dot(integ.discretisation.L)
        row["linear_its_total"] = integ.linear_its
        if not np.isfinite(row["energy"]):
            raise StepError(f"step {n} (t = {t:.6g}): the energy is not finite ({row['energy']})")
        for c in self.columns:
            self.data[c][n] = row[c]
        return row

    def load_rows(self, lines):
        """Fill rows from CSV lines (``step,...`` in the column order; a restart's history)."""
        for line in lines:
            vals = line.split(",")
            for c, v in zip(self.columns, vals):
                self.data[c][int(vals[0])] = float(v)


@dataclass
class Result:
    """What a run produced.

    Attributes:
        timeseries: column name -> numpy array (one entry per step, entry 0 = initial state).
        info: what ``run.json`` holds (parameters, dofs, versions, wall time, ...).
        gap_imposed: per step, min over constraints of (constrained iterate - bound).
        gap_end: per step, min over constraints of (U^{n+1} - bound).
        U, V: final state vectors (PETSc, owned entries); V is Vbar in W, or V in H for the
            consistent block variant.
        discretisation: the :class:`sdm_dolfinx.method.discretisation.Discretisation`.
    """
    timeseries: dict
    info: dict
    gap_imposed: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gap_end: np.ndarray = field(default_factory=lambda: np.zeros(0))
    U: object = None
    V: object = None
    discretisation: object = None

    def displacement(self):
        """The final displacement U as a dolfinx Function of W^h (for plotting, probing, post-processing)."""
        return self._function(self.discretisation.W, self.U, "displacement")

    def velocity(self):
        """The final velocity as a dolfinx Function: Vbar in W^h, or V in H^h for the consistent block variant.

        Only M Vbar is determined by the scheme; with a singular M (dim H^h < dim W^h) Vbar also has
        a component in Ker(M) that carries no kinetic energy (see docs/outputs.md).
        """
        d = self.discretisation
        space = d.H if (d.mass == "consistent") else d.W
        return self._function(space, self.V, "velocity")

    def max_energy_deviation(self):
        """max_n |J^n - J^0| / |J^0| of the discrete energy (Theorem 2: 0 for the midpoint scheme without impact)."""
        E = np.asarray(self.timeseries["energy"])
        return float(np.max(np.abs(E - E[0])) / abs(E[0])) if E.size and E[0] != 0 else float("nan")

    @staticmethod
    def _function(space, vec, name):
        from dolfinx import fem
        f = fem.Function(space, name=name)
        f.x.array[:len(vec.array)] = vec.array
        f.x.scatter_forward()
        return f
