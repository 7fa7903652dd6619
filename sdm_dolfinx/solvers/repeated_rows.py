"""Dense Newton systems whose rows may repeat others: the two passes of a node-to-surface contact where the
faces' vertices meet hold the same two vertices against each other twice (the same constraint, the opposite
normal), and the system on the cached columns is then singular. The displacement is the same for every
split of their force: the minimum-norm solution (least squares) is taken, which splits it equally and does
not depend on the rows' order (on the number of ranks). A system singular otherwise (rows that repeat
others but ask for other values) has no solution: VIError."""
from __future__ import annotations

import warnings

import numpy as np
import numpy.typing as npt
import scipy.linalg

from sdm_dolfinx.solvers.base import VIError

Array = npt.NDArray[np.float64]
#: an LU pivot below this fraction of the largest: rows that repeat others (singular to round-off, whatever
#: the rows' order)
DEPENDENT_PIVOT = 1e-10
#: such rows must agree with the rows they repeat to this much of the system's scale
DEPENDENT_RTOL = 1e-8


def solve_repeated(S: Array, r: Array, contradiction: str) -> Array:
    """x of S x = r (dense, the same on every rank): by LU when its pivots are all above
    :data:`DEPENDENT_PIVOT` of the largest, else the minimum-norm solution, which must satisfy the system
    to :data:`DEPENDENT_RTOL` of its scale (else VIError(``contradiction``))."""
    if S.size == 0:
        return np.zeros(0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)       # an exactly zero pivot: below
        lu = scipy.linalg.lu_factor(S, check_finite=False)
    pivots = np.abs(np.diag(lu[0]))
    if pivots.min() > DEPENDENT_PIVOT * pivots.max():
        return np.asarray(scipy.linalg.lu_solve(lu, r, check_finite=False))
    x = np.linalg.lstsq(S, r, rcond=None)[0]
    scale = float(np.max(np.abs(S))) * float(np.max(np.abs(x), initial=0.0)) + float(np.max(np.abs(r), initial=0.0))
    if float(np.max(np.abs(S @ x - r), initial=0.0)) > DEPENDENT_RTOL * max(scale, 1e-300):
        raise VIError(contradiction)
    return np.asarray(x)
