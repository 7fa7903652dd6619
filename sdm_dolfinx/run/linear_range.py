"""Whether a run stayed where its linear (small-strain) model holds: the largest rotation and strain of
any cell, watched at every recorded step, and one warning at the end of a run that left that range.

The model is linear elasticity: the strain is ε = sym ∇u and the equations are written in the reference
configuration. Both are first-order in ∇u, and what they drop is second order: the Green–Lagrange strain
is ε + ½ ∇uᵀ∇u. Where ∇u is a rotation by ω (its skew part: ω = |skew ∇u|_F / √2 rad, the angle in 2-D,
|½ curl u| in 3-D), the linear model's rigid rotation u = ω × x is strain-free but is not a rotation: it
moves the body's points off their circles to the radius r √(1 + ω²), a stretch ω²/2 (1.25e-3 at 0.05 rad,
the order of the elastic strains in the demos). A disc that rolls turns by ω = (distance rolled)/r, and
its spurious rise r ω²/2 in a bowl is a potential of the order of the pendulum's own: the linear model's
rolling period is 0.61 T0, not the rigid disc's 1.22 T0 (docs/contact.md), however small the amplitude.
Such a result is the linear model's, right to its tolerances and wrong as physics; without a warning
nothing says so. A strain |ε|_F above 0.05 is beyond the small-strain range of any material law.

The warning says what was exceeded, where and when, that the run's answer is the linear model's, and
the remedy: a hyperelastic material (run option ``material``: svk, neo-hookean; docs/finite_strain.md),
whose runs are not watched (their rotations are exact).
"""
from __future__ import annotations

import warnings
from typing import TYPE_CHECKING, Optional

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
import ufl
from dolfinx import fem

from sdm_dolfinx import compat

if TYPE_CHECKING:
    from petsc4py import PETSc

#: the largest cell rotation |skew ∇u|_F / √2 (rad) the linear model is trusted with: its spurious stretch
#: ω²/2 is then 1.25e-3 (module docstring)
ROTATION_TOL = 0.05
#: the largest cell strain |sym ∇u|_F the small-strain model is trusted with
STRAIN_TOL = 0.05


class LinearRangeWarning(UserWarning):
    """A cell rotated or strained beyond :data:`ROTATION_TOL` / :data:`STRAIN_TOL`: one line on rank 0, once
    per run; silence it with ``warnings.simplefilter("ignore", LinearRangeWarning)``."""


class LinearRange:
    """The largest rotation and strain of any cell of a vector displacement over a run's recorded steps.

    Each is evaluated at the cells' midpoints (a DG0 interpolation of ∇u: one cell kernel per cell and
    step, and one reduction); where and when the largest was reached is found (one more collective) only
    when it grows beyond its tolerance.

    Args:
        W: the displacement's space (vector-valued, gdim 2 or 3).
    """

    def __init__(self, W: fem.FunctionSpace) -> None:
        msh = W.mesh
        self.comm = msh.comm
        self.u = fem.Function(W)
        g = ufl.grad(self.u)
        skew, sym = ufl.skew(g), ufl.sym(g)
        expr = ufl.as_vector([ufl.sqrt(ufl.inner(skew, skew) / 2.0), ufl.sqrt(ufl.inner(sym, sym))])
        self.Q = compat.function_space(msh, compat.element("DG", compat.cell_name(msh), 0, (2,)))
        self.q = fem.Function(self.Q)
        self.expr = fem.Expression(expr, compat.interpolation_points(self.Q))
        self.num_cells = msh.topology.index_map(msh.topology.dim).size_local
        #: the DG0 block of each owned cell (not assumed to be the cell's own index)
        self.block_of_cell = np.asarray(compat.dofmap_list(self.Q)[:self.num_cells, 0], dtype=np.int64)
        #: the largest (rotation, strain) so far, and for each (step, t, cell midpoint) once beyond tolerance
        self.largest = np.zeros(2)
        self.where: list[Optional[tuple[int, float, npt.NDArray[np.float64]]]] = [None, None]
        self.warned = False

    @staticmethod
    def applies(shape: tuple[int, ...], gdim: int) -> bool:
        """A displacement of the mesh's dimension (value ``shape`` (gdim,)) in 2-D or 3-D: a scalar field has
        no rotation, 1-D none, and another vector (3 components on a 2-D mesh) no square gradient."""
        return tuple(shape) == (gdim,) and gdim >= 2

    def watch(self, n: int, t: float, U: PETSc.Vec) -> None:
        """Measure the state U (owned dofs) of step ``n`` at time ``t`` (collective)."""
        owned = U.array_r
        self.u.x.array[:owned.size] = owned
        self.u.x.scatter_forward()
        self.q.interpolate(self.expr)
        mine = self.q.x.array.reshape(-1, 2)[self.block_of_cell]          # row k: owned cell k
        local = mine.max(axis=0, initial=0.0)
        now = np.empty(2)
        self.comm.Allreduce(np.ascontiguousarray(local), now, op=MPI.MAX)
        for k, tol in enumerate((ROTATION_TOL, STRAIN_TOL)):
            if now[k] > self.largest[k]:
                self.largest[k] = now[k]
                if now[k] > tol:
                    self.where[k] = (n, t, self._midpoint(mine[:, k], now[k]))

    def _midpoint(self, values: npt.NDArray[np.float64], largest: float) -> npt.NDArray[np.float64]:
        """The midpoint of a cell where ``values`` reaches ``largest`` (on its owner; broadcast)."""
        k = int(np.argmax(values)) if values.size else -1
        has = k >= 0 and values[k] == largest
        owner = self.comm.allreduce(self.comm.rank if has else self.comm.size, op=MPI.MIN)
        x = None
        if self.comm.rank == owner:
            msh = self.Q.mesh
            nodes = compat.entities_to_geometry(msh, msh.topology.dim, np.array([k], dtype=np.int32))
            x = msh.geometry.x[nodes[0]].mean(axis=0)[:msh.geometry.dim]
        return self.comm.bcast(x, root=owner)

    def warn(self) -> None:
        """A :class:`LinearRangeWarning` on rank 0, once, when the run left the range (collective-free)."""
        said = []
        for k, (what, tol, unit) in enumerate((("rotated", ROTATION_TOL, " rad"), ("strained", STRAIN_TOL, ""))):
            reached = self.where[k]
            if reached is None:
                continue
            n, t, x = reached
            at = ", ".join(f"{c:.6g}" for c in x)
            said.append(f"a cell {what} by {self.largest[k]:.3g}{unit} (step {n}, t = {t:.6g}, at ({at}); "
                        f"tolerance {tol:g})")
        if self.warned or not said:
            return
        self.warned = True
        if self.comm.rank == 0:
            # warn_explicit with no source file: one line ("sdm_dolfinx:0: LinearRangeWarning: ...")
            warnings.warn_explicit(
                f"{' and '.join(said)}: beyond the linear (small-strain) model's range, whose rotation "
                f"u = ω × x stretches the body by ω²/2; the run's answer is the linear model's, not the "
                f"physical one: run it with material svk or neo-hookean (finite strain, docs/finite_strain.md)",
                LinearRangeWarning, "sdm_dolfinx", 0)
