"""The files of a run folder: ``run.json``, ``timeseries.csv``, ``solution.xdmf``, ``state.h5``
(and ``checkpoint.npz``, see :mod:`.restart`). docs/outputs.md describes them."""
from pathlib import Path

from sdm_dolfinx.mpiutil import write_json
from sdm_dolfinx.run import checkpoint
from sdm_dolfinx.run.observers import CSVWriter, StateWriter, XDMFWriter


class RunFiles:
    """Open (or, on restart, continue) the files of ``out`` for one run (collective).

    Args:
        out: the folder (created if missing).
        integ: the run's :class:`sdm_dolfinx.method.integrator.Integrator`.
        series: its :class:`sdm_dolfinx.run.result.TimeSeries` (filled with the kept rows on
            restart).
        info: the ``run.json`` dict (written now and by :meth:`update`).
        restart: ``None`` for a new run, else ``(first step, outputs)`` of
            :func:`sdm_dolfinx.run.restart.resume`.
        write_every: the fields are written every K steps.
    """

    def __init__(self, out, integ, series, info, fingerprint, restart, write_every, dt):
        discretisation = integ.discretisation
        self.comm, self.out, self.info, self.dt = discretisation.comm, Path(out), info, dt
        self.write_every = write_every or 10
        comm, out = self.comm, self.out
        if comm.rank == 0:
            out.mkdir(parents=True, exist_ok=True)
            if restart is None:         # a checkpoint of the run this one replaces must not be resumed
                (out / checkpoint.CHECKPOINT).unlink(missing_ok=True)
        comm.Barrier()
        write_json(out / "run.json", info, comm)
        first, outputs = restart if restart is not None else (0, {"solution": False, "state": False})
        if restart is not None:
            rows = checkpoint.truncate_csv(out / "timeseries.csv", first, comm)
            series.load_rows(rows[1:])
            if outputs["solution"]:
                checkpoint.truncate_xdmf(out / "solution.xdmf", first * dt, comm)
        append = restart is not None
        self.csv = CSVWriter(out / "timeseries.csv", series.columns, comm, append=append)
        self.xdmf = XDMFWriter(out / "solution.xdmf", discretisation, integ, append=append and outputs["solution"])
        self.state = StateWriter(out / "state.h5", discretisation, integ, fingerprint, append=append and outputs["state"],
                                 last_step=first)
        self.state_missing = append and not outputs["state"]

    def row(self, row):
        """Append a time-series row to ``timeseries.csv``."""
        self.csv.write(row)

    def fields(self, n, U, V, lam):
        """Write the fields of step ``n`` to ``solution.xdmf`` and ``state.h5``."""
        self.xdmf.write(U, V, lam, lam > 0, n * self.dt)
        self.state.write(U, V, n, n * self.dt)

    def due(self, n, nsteps):
        """Whether step ``n``'s fields are written (every ``write_every`` steps, and the last)."""
        return n % self.write_every == 0 or n == nsteps

    def update(self, **entries):
        """Update ``run.json`` with ``entries``."""
        self.info.update(entries)
        write_json(self.out / "run.json", self.info, self.comm)

    def close(self):
        self.csv.close()
