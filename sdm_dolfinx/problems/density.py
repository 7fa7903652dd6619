"""A Problem's density ``rho``: one number, or a dolfinx Function on its mesh (any element; DG0 for a
density per cell, e.g. per body of a mesh of several bodies), in every mass form as ``rho u.w dx``."""
from __future__ import annotations

from typing import Any

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.problems.errors import ProblemInputError


def is_field(rho: Any) -> bool:
    """``rho`` is a Function (it has a function space and values), not a number."""
    return hasattr(rho, "function_space") and hasattr(rho, "x")


def validate(problem: Any) -> None:
    """Refuse, in one line naming the problem (on every rank), a density that is not a finite number > 0 or
    a Function on the problem's mesh with finite values > 0."""
    rho, name = problem.rho, problem.name
    if is_field(rho):
        msh = problem.mesh
        if hasattr(msh, "comm") and rho.function_space.mesh is not msh:
            raise ProblemInputError(f"problem {name!r}: rho is a Function on another mesh than the problem's")
        values = np.asarray(rho.x.array)
        bad = int(np.count_nonzero(~(np.isfinite(values) & (values > 0.0))))
        comm = getattr(msh, "comm", MPI.COMM_SELF)
        if comm.allreduce(bad, op=MPI.SUM):
            raise ProblemInputError(f"problem {name!r}: rho, a Function, has values that are not finite numbers > 0 "
                                    f"(the density of the mass forms rho u.w dx)")
        return
    if isinstance(rho, bool) or not isinstance(rho, (int, float, np.integer, np.floating)) \
            or not (np.isfinite(rho) and rho > 0):
        raise ProblemInputError(f"problem {name!r}: rho must be a finite number > 0 or a Function on the mesh (a "
                                f"density per cell), the density of the mass forms rho u.w dx (got {rho!r})")


def form(problem: Any) -> Any:
    """The density as it enters a UFL form: the Function itself, or a ``fem.Constant`` of the number."""
    from dolfinx import fem
    from petsc4py import PETSc
    if is_field(problem.rho):
        return problem.rho
    return fem.Constant(problem.mesh, PETSc.ScalarType(problem.rho))
