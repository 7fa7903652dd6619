"""What a contact treatment is given: :class:`StepContext`, built by the Integrator once K is built.

A treatment sees the step's matrix and the discretisation, never the Integrator: it cannot
reach the scheme, the step solver of another treatment or the run's state, and a new
treatment (gap rows, obstacles, two bodies) can tell from this one record what it may rely on.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

from petsc4py import PETSc

if TYPE_CHECKING:
    from sdm_dolfinx.method.discretisation import Discretisation


@dataclass(frozen=True)
class StepContext:
    """The read-only context of a contact treatment (:func:`sdm_dolfinx.contact.make`).

    The fields cannot be rebound; the objects they hold are shared with the Integrator, so a
    treatment reads them and does not change them (it builds its own vectors and matrices).

    Attributes:
        K: the constant step matrix K = c_M M + c_A A of the scheme (Dirichlet rows and columns
            eliminated), the matrix of K X = b + lam(X).
        discretisation: the :class:`~sdm_dolfinx.method.discretisation.Discretisation` (spaces,
            A, B, C, constrained dofs ``cdofs``, bounds ``lb``, lumped measures ``cmeasure``, problem).
        dt: the time step.
        block: K is the (U, V) block matrix of mass ``"consistent"`` (not symmetric positive
            definite), else the M formulation's.
        factor_matrix: a sparser matrix whose factorisation solves with K (the augmented matrix
            of :func:`~sdm_dolfinx.solvers.sparse_factor_matrix`), or None.
    """

    K: PETSc.Mat
    discretisation: Discretisation
    dt: float
    block: bool = False
    factor_matrix: Optional[PETSc.Mat] = None
