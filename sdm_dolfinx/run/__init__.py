"""Running: the time loop (:func:`simulate`), one step of a scheme (:mod:`.integrator`), the
time series a run records (:mod:`.result`), probes, checkpoints and restarts (:mod:`.restart`),
signals, and :func:`launch`, which runs a declared problem by name (the command line, the studies
and the demos use it). The run folder's files are :mod:`sdm_dolfinx.io`'s."""
from sdm_dolfinx.run.launch import RUN_DEFAULTS, RunInputError, RunPlan, launch, plan  # noqa: F401
from sdm_dolfinx.run.result import BASE_COLUMNS, Result, TimeSeries, num_steps  # noqa: F401
from sdm_dolfinx.run.observe import ObserveError, State  # noqa: F401
from sdm_dolfinx.run.signals import Interrupted  # noqa: F401
from sdm_dolfinx.run.simulate import SolverSetupError, simulate  # noqa: F401
