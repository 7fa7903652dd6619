"""Running: the time loop (:func:`simulate`), its files and checkpoints, and :func:`launch`,
which runs a declared problem by name (the command line, the study and the demos use it)."""
from sdm_dolfinx.run.checkpoint import CheckpointError  # noqa: F401
from sdm_dolfinx.run.folder import FolderInUseError, RunFolderError, check_out, read_info  # noqa: F401
from sdm_dolfinx.run.launch import RUN_DEFAULTS, RunInputError, RunPlan, launch, plan  # noqa: F401
from sdm_dolfinx.run.outputs import RunFileError  # noqa: F401
from sdm_dolfinx.run.result import BASE_COLUMNS, Result, TimeSeries, num_steps  # noqa: F401
from sdm_dolfinx.run.signals import Interrupted  # noqa: F401
from sdm_dolfinx.run.simulate import SolverSetupError, simulate  # noqa: F401
