"""Contact between deformable bodies: a Problem's ``contact_pairs``.

Several bodies are one mesh whose connected parts are the bodies (each with its own material
through the forms ``a(u, w)`` and ``l(w)``, e.g. ``dx(subdomain_id)`` or a DG0 coefficient). A
:class:`ContactPair` names two boundary parts of it by their facets: the vertices of the
``slave`` facets must stay outside the body behind the ``master`` facets (node-to-surface, one
pass). The discretisation builds the gap rows (:mod:`sdm_dolfinx.method.body_rows`); this module
only declares and checks the data.

A Problem with contact pairs declares no other constraint: ``constraint_vertices=None`` (the
pairs' slave facets name the constrained vertices), ``lower_bound=None`` and no ``obstacles``.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.problems.dirichlet import MeshEntities
from sdm_dolfinx.problems.errors import ProblemInputError

if TYPE_CHECKING:
    from dolfinx.mesh import Mesh


@dataclass(frozen=True)
class ContactPair:
    """Two boundary parts that may touch: every vertex of ``slave`` stays outside the body whose
    boundary facets are ``master`` (frictionless, node-to-surface, the master's outward normal).

    Attributes:
        slave: ``mesh -> local facet indices`` (exterior facets): their vertices are the
            constrained nodes.
        master: ``mesh -> local facet indices`` (exterior facets of another body): the surface
            the slave vertices are projected on.
        name: the pair's name in messages (letters, digits, ``_``).
    """
    slave: MeshEntities
    master: MeshEntities
    name: str = "contact"

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "kind": "node-to-surface (slave vertices on the master facets), frictionless"}


def slave_vertices(pairs: Sequence[ContactPair], mesh: Mesh) -> npt.NDArray[np.int32]:
    """The local vertices of the slave facets of every pair (sorted, unique)."""
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim - 1, 0)
    f2v = mesh.topology.connectivity(tdim - 1, 0).array.reshape(-1, tdim)
    facets = np.concatenate([np.asarray(p.slave(mesh), dtype=np.int64).reshape(-1) for p in pairs]) \
        if pairs else np.zeros(0, dtype=np.int64)
    return np.unique(f2v[facets].reshape(-1)).astype(np.int32) if facets.size else np.zeros(0, dtype=np.int32)


def constrained_vertices(problem: Any, mesh: Mesh) -> npt.NDArray[np.int32]:
    """A Problem's constrained vertices: ``constraint_vertices(mesh)``, or the slave facets' vertices
    of its ``contact_pairs``."""
    pairs = getattr(problem, "contact_pairs", ())
    if pairs:
        return slave_vertices(pairs, mesh)
    if problem.constraint_vertices is None:
        raise ProblemInputError(f"problem {problem.name!r}: constraint_vertices is None and there are no "
                                f"contact_pairs: declare the constrained vertices (an empty array: none)")
    return np.asarray(problem.constraint_vertices(mesh), dtype=np.int32)
