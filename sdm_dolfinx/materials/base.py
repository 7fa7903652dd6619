"""What a hyperelastic material is: a strain energy density psi(C) of the right Cauchy-Green tensor.

Total Lagrangian: u is the displacement from the reference configuration, F = I + grad u,
C = F^T F, E = (C - I) / 2; the second Piola-Kirchhoff stress is S = 2 dpsi/dC and the first
P = F S, so that the internal force is int P : grad w dx. In 2-D the body is in plane strain
(C_33 = 1: psi's ``d`` is 2). Every material here linearises at F = I to Hooke's law with the
Problem's Lame parameters, which the run checks (:mod:`sdm_dolfinx.method.finite_strain`).
"""
from __future__ import annotations

from typing import Any, Optional

import ufl

from sdm_dolfinx.errors import SdmError

#: a :class:`~sdm_dolfinx.problems.Problem` (a layer above: not imported)
Problem = Any

#: the name of the linear model (the Problem's own a(u, w); the default)
LINEAR = "linear"
#: a UFL expression (ufl has no annotations)
UFL = Any


class MaterialError(SdmError, ValueError):
    """A material refused: unknown, or missing what it needs from the Problem (one line)."""


class Material:
    """A strain energy density psi(C) (subclasses define :meth:`psi`).

    Attributes:
        name: the registry's name (the ``--material`` choice).
        help: one line for ``--help`` and the docs.
        quadratic: psi is quadratic in E (Saint Venant-Kirchhoff): the energy-momentum scheme's
            stress S((C^n + C^{n+1})/2) is exact (Simo-Tarnow), no discrete-gradient correction.
    """
    name: str = ""
    help: str = ""
    quadratic: bool = False

    def refusal(self, problem: Problem) -> Optional[str]:
        """Why this material cannot model ``problem`` (one line), or None (default: a vector u
        in 2-D or 3-D whose ``parameters`` give ``lame_lambda`` and ``lame_mu``)."""
        shape, gdim = tuple(problem.shape), problem.mesh.geometry.dim
        if len(shape) != 1 or shape[0] != gdim or gdim < 2:
            return (f"material {self.name!r} is a hyperelastic law of a vector displacement in 2-D or 3-D; "
                    f"problem {problem.name!r} solves a {'scalar' if not shape else f'{shape[0]}-vector'} field "
                    f"in {gdim}-D: use material 'linear'")
        missing = [k for k in ("lame_lambda", "lame_mu") if k not in (problem.parameters or {})]
        if missing:
            return (f"material {self.name!r} needs the Lame parameters in problem {problem.name!r}'s parameters "
                    f"({' and '.join(missing)} missing): declare them, or write Problem.strain_energy and use "
                    f"material 'problem'")
        return None

    def lame(self, problem: Problem) -> tuple[float, float]:
        """(lambda, mu) of ``problem`` (its ``parameters``)."""
        p = problem.parameters
        return float(p["lame_lambda"]), float(p["lame_mu"])

    def psi(self, C: UFL, problem: Problem) -> UFL:
        """The strain energy density at C (a (d, d) UFL tensor) for ``problem``'s constants."""
        raise NotImplementedError


def dimension(C: UFL) -> int:
    """d of a (d, d) tensor C."""
    return int(ufl.shape(C)[0])


def green_lagrange(C: UFL) -> UFL:
    """E = (C - I) / 2."""
    return 0.5 * (C - ufl.Identity(dimension(C)))
