"""Running: :func:`simulate` (the one entry point: check every input, then run) and :func:`plan`
(check without running); the run options declared once (:mod:`.options`); the time loop
(:mod:`.loop`), one step of a scheme (:mod:`.integrator`), the time series a run records
(:mod:`.result`), probes, checkpoints and restarts (:mod:`.restart`), signals, the memory a run
needs (:mod:`.memory`). The run folder's files are :mod:`sdm_dolfinx.io`'s."""
from sdm_dolfinx.run.loop import SolverSetupError  # noqa: F401
from sdm_dolfinx.run.options import RunInputError, grouped  # noqa: F401
from sdm_dolfinx.run.planning import RunPlan, plan  # noqa: F401
from sdm_dolfinx.run.result import BASE_COLUMNS, Result, TimeSeries, num_steps  # noqa: F401
from sdm_dolfinx.run.observe import ObserveError, State  # noqa: F401
from sdm_dolfinx.run.signals import Interrupted  # noqa: F401
from sdm_dolfinx.run.simulate import launch, simulate  # noqa: F401

__all__ = ["simulate", "plan", "RunPlan", "Result", "TimeSeries", "State", "BASE_COLUMNS", "num_steps", "grouped",
           "launch", "RunInputError", "SolverSetupError", "ObserveError", "Interrupted"]
