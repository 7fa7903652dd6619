"""The constrained boundary's sink below its constrained vertices (P2's mid-edge nodes under the vertex
constraint (13)), watched at every recorded step, and one warning at the end of a run where it mattered.

The time series' column ``gap_min_boundary`` reports the face at every node; :class:`BoundarySink` keeps
the deepest sink and the run's displacement scale, and :meth:`BoundarySink.warn` says it in one line.
"""
from __future__ import annotations

import warnings
from typing import TYPE_CHECKING, Optional

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.method import gaps

if TYPE_CHECKING:
    from petsc4py import PETSc

    from sdm_dolfinx.method.discretisation import Discretisation

#: the column added when the constrained boundary has dofs: min over every dof of W^h on it (P2 mid-edge
#: nodes included) of U_c - bound at the end of the step (the constraint (13) holds at vertices only)
BOUNDARY_GAP = "gap_min_boundary"
#: at the end of a run, warn (once) when a dof of the constrained boundary went below the bound by more
#: than the constrained vertices did (the midpoint scheme's own O(dt) dip of U^{n+1}) plus a tolerance:
#: the smaller of BOUNDARY_GAP_TOL times the diameter of the constrained boundary (the diagonal of its
#: bounding box) and BOUNDARY_SINK_RTOL times the run's displacement scale (the largest spread max - min
#: of the bounded component over the body during the run, :func:`~sdm_dolfinx.method.gaps.displacement_spread`),
#: and at least BOUNDARY_GAP_FLOOR times the diameter (round-off). The displacement scale makes a sink that
#: matters to the run warn however small the body's motion (a P2 face pushed by 10 um sinks 1.7 um between
#: its vertices: 17 %, far below 1e-3 x a 20 mm boundary); the whole run's scale, not the scale so far,
#: keeps the first instants of an impact (a sink against a deformation that has hardly begun) from
#: deciding alone
BOUNDARY_GAP_TOL = 1e-3
BOUNDARY_SINK_RTOL = 1e-2
BOUNDARY_GAP_FLOOR = 1e-9


class BoundaryGapWarning(UserWarning):
    """The constrained boundary sinks below the bound between constrained vertices (P2 mid-edge
    nodes): one line on rank 0, once per run; silence it with ``warnings.simplefilter("ignore",
    BoundaryGapWarning)``."""


class BoundarySink:
    """The deepest sink of the constrained boundary below the constrained vertices over a run's recorded
    steps, and the run's displacement spread (:data:`BOUNDARY_SINK_RTOL`).

    Args:
        discretisation: the run's Discretisation (it has a constrained boundary: ``num_boundary_dofs``).
    """

    def __init__(self, discretisation: Discretisation) -> None:
        self.discretisation = d = discretisation
        self.comm = d.comm
        lo, hi = np.empty(3), np.empty(3)
        self.comm.Allreduce(np.ascontiguousarray(d.bx.min(axis=1, initial=np.inf)), lo, op=MPI.MIN)
        self.comm.Allreduce(np.ascontiguousarray(d.bx.max(axis=1, initial=-np.inf)), hi, op=MPI.MAX)
        self.diameter = float(np.linalg.norm(hi - lo))
        self.spread = 0.0                   # the run's displacement scale so far (BOUNDARY_SINK_RTOL)
        #: the deepest sink of the boundary below the constrained vertices so far: (sink, step, t, where)
        self.sink: tuple[float, int, float, Optional[npt.NDArray[np.float64]]] = (0.0, 0, 0.0, None)
        self.warned = False

    def track(self, n: int, t: float, U: PETSc.Vec, gap: float) -> None:
        """Keep the run's displacement spread and the deepest sink of the constrained boundary below
        the constrained vertices (with where it was: one more collective when it deepens); ``gap``: the
        step's ``gap_min_boundary``."""
        d = self.discretisation
        self.spread = max(self.spread, gaps.displacement_spread(d, U.array_r))
        sink = min(gaps.vertex_gap(d, U.array_r, t), 0.0) - gap
        if sink > self.sink[0]:
            self.sink = (sink, n, t, gaps.boundary_gap_where(d, U.array_r, t))

    @property
    def tol(self) -> float:
        """How far the constrained boundary may sink below the constrained vertices before
        :meth:`warn` warns (:data:`BOUNDARY_GAP_TOL`, :data:`BOUNDARY_SINK_RTOL`)."""
        return max(BOUNDARY_GAP_FLOOR * self.diameter,
                   min(BOUNDARY_GAP_TOL * self.diameter, BOUNDARY_SINK_RTOL * self.spread))

    def warn(self) -> None:
        """A :class:`BoundaryGapWarning` on rank 0, once, when the constrained boundary sank below the
        bound between the constrained vertices by more than :attr:`tol` in the steps recorded
        (a restarted run: those since the restart). Called at the end of the run (collective)."""
        sink, n, t, x = self.sink
        if self.warned or sink <= self.tol or x is None:
            return
        self.warned = True
        if self.comm.rank == 0:
            where = ", ".join(f"{c:.6g}" for c in x)
            share = f"{sink / self.spread:.1%}" if self.spread else "all"
            # warn_explicit with no source file: one line ("sdm_dolfinx:0: BoundaryGapWarning: ...")
            warnings.warn_explicit(
                f"step {n} (t = {t:.6g}): the constrained boundary sank {sink:.3g} below its constrained vertices "
                f"at ({where}), {share} of the run's displacement spread {self.spread:.3g} (tolerance "
                f"{self.tol:.3g}; the deepest of the run); {self._remedy()}; every step's minimum "
                f"is in the column {BOUNDARY_GAP}", BoundaryGapWarning, "sdm_dolfinx", 0)

    def _remedy(self) -> str:
        """Where the run's constraint holds, and the options that hold the face between the vertices."""
        if getattr(self.discretisation, "weighted_rows", None) is not None:
            return ("the weighted gap holds the face on average between its vertices: constrain='nodes' "
                    "(--constrain nodes) holds every node of it")
        bodies = getattr(self.discretisation, "body_rows", None)
        if bodies is not None and self.discretisation.constrain == "weighted":
            return "the weighted gap holds the slave face on average between its vertices"
        if bodies is not None:
            return ("the contact pairs hold the slave vertices only: constrain='weighted' (--constrain weighted) holds "
                    "the slave face between them")
        if getattr(self.discretisation, "obstacle_rows", None) is not None:
            return ("the obstacles hold the constrained vertices only: constrain='nodes' (--constrain nodes) holds "
                    "every node of the face")
        return ("the constraint holds at vertices only (eq. (13)): constrain='weighted' (--constrain weighted) holds "
                "the face between them, constrain='nodes' (--constrain nodes) at every node")
