"""Mesh entities chosen by where they are: the facets a :class:`~.contact_pairs.ContactPair` names and the
cells a :class:`~.bodies.Body` names, as ``mesh -> local indices`` functions.

Bodies that touch share positions but not entities: a facet on the plane where two bodies meet belongs to
one of them, told apart by the side its cell lies on (``side``, a test on the cell's midpoint).

    ContactPair(slave=facets_where(lambda x: np.isclose(x[1], 0.0), side=lambda c: c[1] > 0.0),
                master=facets_where(lambda x: np.isclose(x[1], 0.0), side=lambda c: c[1] < 0.0), name="seam")
    Body("upper", cells_where(lambda c: c[1] > 0.0))
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any, Optional

import numpy as np
import numpy.typing as npt

Points = npt.NDArray[np.float64]
Test = Callable[[Points], Any]


def facets_where(on: Test, side: Optional[Test] = None) -> Callable[[Any], npt.NDArray[np.int32]]:
    """``mesh -> local facet indices``: the exterior facets whose points all satisfy ``on(x)`` (x: (3, n), as
    dolfinx's ``locate_entities_boundary`` asks) and, with ``side``, whose cell's midpoint c (3, m) satisfies
    ``side(c)``."""
    def found(mesh: Any) -> npt.NDArray[np.int32]:
        from dolfinx import mesh as dmesh
        fdim = mesh.topology.dim - 1
        mesh.topology.create_connectivity(fdim, fdim + 1)
        facets = np.asarray(dmesh.locate_entities_boundary(mesh, fdim, on), dtype=np.int32)
        if side is None or not len(facets):
            return facets
        f2c = mesh.topology.connectivity(fdim, fdim + 1)
        mid = dmesh.compute_midpoints(mesh, fdim + 1, f2c.array[f2c.offsets[facets]])
        return facets[np.asarray(side(mid.T), dtype=bool)]
    return found


def cells_where(side: Test) -> Callable[[Any], npt.NDArray[np.int32]]:
    """``mesh -> local cell indices`` (ghosts included): the cells whose midpoint c (3, m) satisfies
    ``side(c)``."""
    def found(mesh: Any) -> npt.NDArray[np.int32]:
        from dolfinx import mesh as dmesh
        tdim = mesh.topology.dim
        im = mesh.topology.index_map(tdim)
        cells = np.arange(im.size_local + im.num_ghosts, dtype=np.int32)
        if not len(cells):
            return cells
        return cells[np.asarray(side(dmesh.compute_midpoints(mesh, tdim, cells).T), dtype=bool)]
    return found
