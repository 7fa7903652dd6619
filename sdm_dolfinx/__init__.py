"""sdm_dolfinx: the singular dynamic method (Y. Renard, JCAM 234 (2010) 906-923) on FEniCSx.

Quick use::

    from sdm_dolfinx import simulate
    from sdm_dolfinx.problems import membrane
    result = simulate(membrane.problem(N=10), pair="P1+/P0", scheme="midpoint", dt=1e-3, T=0.8)
    result.timeseries["energy"]

The package's folders are its layers (docs/architecture.md): ``problems`` (what is solved),
``method`` (pairs, discretisation, time schemes), ``solvers`` (the step's variational
inequality), ``run`` (the time loop and its files), ``post`` (reading runs back), ``paper``
(the paper's study) and ``cli`` (the command line).
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

from sdm_dolfinx.problems import disc, membrane  # noqa: E402
from sdm_dolfinx.problems.base import Problem  # noqa: E402
from sdm_dolfinx.method.discretisation import Discretisation  # noqa: E402
from sdm_dolfinx.errors import SdmError, StepError  # noqa: E402
from sdm_dolfinx.run.integrator import SCHEMES, Integrator  # noqa: E402
from sdm_dolfinx.method.pairs import MASS_TREATMENTS, PAIRS, Pair, get_pair  # noqa: E402
from sdm_dolfinx.run import Result, launch, simulate  # noqa: E402
from sdm_dolfinx.solvers import VIError  # noqa: E402

__all__ = ["SdmError", "membrane", "disc", "Discretisation", "Integrator", "SCHEMES", "StepError", "PAIRS", "Pair",
           "get_pair", "MASS_TREATMENTS", "Problem", "Result", "simulate", "launch", "VIError"]
__version__ = "0.1.0"
