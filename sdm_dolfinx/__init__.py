"""sdm_dolfinx: the singular dynamic method (Y. Renard, JCAM 234 (2010) 906-923) on FEniCSx.

Quick use::

    from sdm_dolfinx import simulate
    result = simulate("membrane", {"N": 10}, pair="P1+/P0", scheme="midpoint", dt=1e-3, T=0.8)
    result.timeseries["energy"]

``simulate`` runs a declared problem by name (or a problem file, or a ``ProblemSpec``) with its
parameters, or a built :class:`Problem` (``membrane.problem(N=10)``); ``plan`` checks the same
inputs without running. The package's folders are its layers (docs/architecture.md).
"""
import logging

import ffcx  # noqa: F401  (its logging.basicConfig creates the root handler)

# The JIT compiler's build steps log "INFO:root:running build_ext" (setuptools raises the
# root logger's level while it compiles): keep the console to warnings and errors.
for _h in logging.getLogger().handlers:
    _h.setLevel(logging.WARNING)
# ffcx also routes Python warnings into logging ("WARNING:py.warnings:FILE:LINE: ..." and a
# blank line): our warnings (e.g. BoundaryGapWarning) are one line each, shown by Python itself.
logging.captureWarnings(False)

from sdm_dolfinx.errors import SdmError, StepError  # noqa: E402
from sdm_dolfinx.params import OptionError, Param  # noqa: E402
from sdm_dolfinx.problems import Body, ContactPair, DirichletPart, Problem, ProblemInputError, ProblemSpec  # noqa: E402
from sdm_dolfinx.problems import ball, bar, block, disc, membrane, rod1d  # noqa: E402
from sdm_dolfinx.problems import register as register_problem  # noqa: E402
from sdm_dolfinx.method.errors import DiscretisationError  # noqa: E402
from sdm_dolfinx.method.pairs import Pair  # noqa: E402
from sdm_dolfinx.method.pairs import register as register_pair  # noqa: E402
from sdm_dolfinx.schemes import Scheme  # noqa: E402
from sdm_dolfinx.schemes import register as register_scheme  # noqa: E402
from sdm_dolfinx.contact import register as register_contact  # noqa: E402
from sdm_dolfinx.solvers import register as register_step_solver  # noqa: E402
from sdm_dolfinx.materials import Material, MaterialError  # noqa: E402
from sdm_dolfinx.materials import register as register_material  # noqa: E402
from sdm_dolfinx.io import CheckpointError, RunFolderError  # noqa: E402
from sdm_dolfinx.run import Interrupted, Result, RunInputError, SolverSetupError, plan, simulate  # noqa: E402

__all__ = ["simulate", "plan", "Result", "Problem", "DirichletPart", "ContactPair", "Body", "ProblemSpec", "Param", "Pair", "Scheme",
           "Material", "register_problem", "register_pair", "register_scheme", "register_contact", "register_step_solver",
           "register_material", "SdmError", "StepError", "RunInputError", "ProblemInputError", "OptionError",
           "DiscretisationError", "MaterialError",
           "Interrupted", "SolverSetupError", "CheckpointError", "RunFolderError",
           "ball", "bar", "block", "disc", "membrane", "rod1d"]
__version__ = "0.1.0"
