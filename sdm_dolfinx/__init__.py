"""sdm_dolfinx: the singular dynamic method (Y. Renard, JCAM 234 (2010) 906-923) on FEniCSx.

Quick use::

    from sdm_dolfinx import membrane, simulate
    result = simulate(membrane.Problem(N=10), pair="P1+/P0", scheme="midpoint", dt=1e-3, T=0.8)
    result.timeseries["energy"]
"""
import logging

import ffcx  # noqa: F401  (its logging.basicConfig creates the root handler)

# The JIT compiler's build steps log "INFO:root:running build_ext" (setuptools raises the
# root logger's level while it compiles): keep the console to warnings and errors.
for _h in logging.getLogger().handlers:
    _h.setLevel(logging.WARNING)

from . import membrane  # noqa: E402
from .discretisation import Discretisation  # noqa: E402
from .integrator import SCHEMES, Integrator, StepError  # noqa: E402
from .pairs import MASS_TREATMENTS, PAIRS, Pair, get_pair  # noqa: E402
from .problem import Problem  # noqa: E402
from .simulate import Result, simulate  # noqa: E402
from .vi import VIError  # noqa: E402

__all__ = ["membrane", "Discretisation", "Integrator", "SCHEMES", "StepError", "PAIRS", "Pair", "get_pair",
           "MASS_TREATMENTS", "Problem", "Result", "simulate", "VIError"]
__version__ = "0.1.0"
