"""Contact between deformable bodies: a Problem's ``contact_pairs``.

Several bodies are one mesh whose connected parts are the bodies (each with its own material
through the forms ``a(u, w)`` and ``l(w)``, e.g. ``dx(subdomain_id)`` or a DG0 coefficient). A
:class:`ContactPair` names two boundary parts of it by their facets: the vertices of the
``slave`` facets must stay outside the body behind the ``master`` facets (node-to-surface, one
pass). :func:`~sdm_dolfinx.problems.selectors.facets_where` builds either side from where its facets are. The discretisation builds the gap rows (:mod:`sdm_dolfinx.method.body_rows`); this module
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
    boundary facets are ``master`` (node-to-surface, the master's outward normal; frictionless, or with the
    run's ``friction`` on the slave vertices' slip relative to the master).

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
        return {"name": self.name, "kind": "node-to-surface (slave vertices on the master facets; friction: the run's)"}


def slave_facets(pairs: Sequence[ContactPair], mesh: Mesh) -> npt.NDArray[np.int32]:
    """The local facets of every pair's slave side (sorted, unique): where a Problem with several pairs (or
    two passes) integrates its ``constraint_measure``, and the weighted gap its weights."""
    return np.unique(np.concatenate([np.asarray(pair.slave(mesh), dtype=np.int32) for pair in pairs]
                                    + [np.zeros(0, dtype=np.int32)])).astype(np.int32)


def slave_vertices(pairs: Sequence[ContactPair], mesh: Mesh) -> npt.NDArray[np.int32]:
    """The local vertices of the slave facets of every pair (sorted, unique).

    Raises:
        ProblemInputError: a pair's slave facets are not exterior facets of the mesh (indices out of
            range, or interior facets); on this rank only: callers refuse on every rank.
    """
    from dolfinx import mesh as dmesh
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim - 1, 0)
    mesh.topology.create_connectivity(tdim - 1, tdim)
    f2v = mesh.topology.connectivity(tdim - 1, 0).array.reshape(-1, tdim)
    exterior = np.asarray(dmesh.exterior_facet_indices(mesh.topology), dtype=np.int64)
    found = []
    for p in pairs:
        facets = np.asarray(p.slave(mesh)).reshape(-1)
        if facets.size and not np.issubdtype(facets.dtype, np.integer):
            raise ProblemInputError(f"contact pair {p.name!r}: slave returned {facets.dtype} values, not facet indices")
        if facets.size and (facets.min() < 0 or facets.max() >= len(f2v)):
            raise ProblemInputError(f"contact pair {p.name!r}: slave returned facet indices outside 0..{len(f2v) - 1}")
        if not np.all(np.isin(facets, exterior)):
            raise ProblemInputError(f"contact pair {p.name!r}: slave names {int(np.sum(~np.isin(facets, exterior)))} "
                                    f"interior facets (the slave and master sides are boundary facets)")
        found.append(facets.astype(np.int64))
    facets = np.concatenate(found) if found else np.zeros(0, dtype=np.int64)
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
