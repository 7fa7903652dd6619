"""The bodies of a mesh of several bodies: a Problem's ``bodies``, for the per-body time-series columns.

A :class:`Body` names a set of cells (``mesh -> local cell indices``). Each body adds the columns
``momentum_<name>_<x|y|z>`` (e^T M Vbar with e the unit translation of that body), ``kinetic_<name>``
(1/2 Vbar_b^T M Vbar_b) and ``elastic_<name>`` (1/2 U_b^T A U_b), U_b and Vbar_b the fields restricted to
the body's dofs (:mod:`sdm_dolfinx.run.body_columns`). The bodies must not share a dof: M and A then
split into the bodies' blocks, and the columns of all the bodies add up to the run's.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from sdm_dolfinx.problems.dirichlet import MeshEntities
from sdm_dolfinx.problems.errors import ProblemInputError


@dataclass(frozen=True)
class Body:
    """A body of the mesh: its name (letters, digits, ``_``: its columns' names) and its cells
    (``mesh -> local cell indices``, ghosts allowed)."""
    name: str
    cells: MeshEntities


def validate(problem: Any) -> None:
    """Refuse, in one line, bodies that are not :class:`Body` objects with distinct word names, or on a
    scalar u."""
    bodies: Sequence[Any] = problem.bodies
    if isinstance(bodies, (str, bytes)) or not isinstance(bodies, (list, tuple)):
        raise ProblemInputError(f"problem {problem.name!r}: bodies must be a list of Body (got {type(bodies).__name__})")
    if not bodies:
        return
    bad = [type(b).__name__ for b in bodies if not isinstance(b, Body)]
    if bad:
        raise ProblemInputError(f"problem {problem.name!r}: bodies must hold Body objects, not {bad[0]}")
    names = [b.name for b in bodies]
    if any(not (isinstance(n, str) and n and n.replace("_", "a").isalnum()) for n in names) or \
            len(set(names)) != len(names):
        raise ProblemInputError(f"problem {problem.name!r}: body names must be distinct words of letters, digits and "
                                f"'_' (got {', '.join(map(repr, names))})")
    if not problem.shape:
        raise ProblemInputError(f"problem {problem.name!r}: bodies take a vector u (their momenta per component)")
