"""Meshes and geometry across dolfinx versions: creating a mesh from arrays or a gmsh model,
bounding-box trees and point location, geometry node indices. Imports nothing of ours but
:mod:`sdm_dolfinx.compat.version`."""
from typing import Any

import numpy as np
from dolfinx import geometry

from sdm_dolfinx.compat.version import DOLFINX_VERSION, NEW_API


def geometry_degree(msh: Any) -> int:
    """The polynomial degree of the mesh's coordinate element (2 for gmsh's curved P2 meshes).

    0.5-0.10: ``geometry.cmap``; 0.11 deprecates it for ``geometry.cmaps[0]`` (python/dolfinx/mesh.py
    at v0.11.0).
    """
    if DOLFINX_VERSION >= (0, 11):  # pragma: no cover
        return int(msh.geometry.cmaps[0].degree)
    return int(msh.geometry.cmap.degree)


def create_mesh(comm, cells, x, domain):
    """``dolfinx.mesh.create_mesh`` from cells (global node indices, dolfinx's node order), node
    coordinates ``x`` and the coordinate element ``domain`` (a ``ufl.Mesh``); dolfinx partitions
    the cells over ``comm``.

    0.5-0.9 take ``(comm, cells, x, domain)``; 0.10 and 0.11 take the element before the
    coordinates, ``(comm, cells, domain, x)`` (python/dolfinx/mesh.py at v0.10.0, v0.11.0).
    """
    from dolfinx import mesh as dmesh
    if DOLFINX_VERSION >= (0, 10):  # pragma: no cover
        return dmesh.create_mesh(comm, cells, domain, x)
    return dmesh.create_mesh(comm, cells, x, domain)


def model_to_mesh(model, comm, rank, gdim):
    """gmsh model -> (mesh, cell_tags, facet_tags).

    ``dolfinx.io.gmshio.model_to_mesh`` returns that tuple up to 0.9; 0.10 has
    ``dolfinx.io.gmsh.model_to_mesh`` returning a ``MeshData``.
    """
    if DOLFINX_VERSION >= (0, 10):  # pragma: no cover
        from dolfinx.io import gmsh as gmsh_io
        data = gmsh_io.model_to_mesh(model, comm, rank, gdim=gdim)
        return data.mesh, data.cell_tags, data.facet_tags
    from dolfinx.io import gmshio
    msh, ct, ft = gmshio.model_to_mesh(model, comm, rank, gdim=gdim)
    return msh, ct, ft


def bounding_box_tree(msh):
    """The cells' bounding-box tree of ``msh`` (``BoundingBoxTree`` in 0.5, ``bb_tree`` later)."""
    if NEW_API:  # pragma: no cover
        return geometry.bb_tree(msh, msh.topology.dim)
    return geometry.BoundingBoxTree(msh, msh.topology.dim)


def colliding_cells(msh, tree, points):
    """For each point (rows of an (n, 3) array), the local cells containing it."""
    if NEW_API:  # pragma: no cover
        cand = geometry.compute_collisions_points(tree, points)
    else:
        cand = geometry.compute_collisions(tree, points)
    return geometry.compute_colliding_cells(msh, cand, points)


def _num_cells(msh):
    """Local cells, owned and ghost."""
    imap = msh.topology.index_map(msh.topology.dim)
    return imap.size_local + imap.num_ghosts


def mesh_geometry_dofmap(msh: Any) -> Any:
    """Cell -> geometry node indices, as a 2-D (num_cells, nodes_per_cell) array.

    0.5: an AdjacencyList, reshaped; 0.7-0.10: ``geometry.dofmap``; 0.11 deprecates that for
    ``geometry.dofmaps[0]`` (one per cell type; ours have one).
    """
    if DOLFINX_VERSION >= (0, 11):  # pragma: no cover
        return msh.geometry.dofmaps[0]
    if NEW_API:  # pragma: no cover
        return msh.geometry.dofmap
    nodes = msh.geometry.cmap.create_dof_layout().num_dofs
    return msh.geometry.dofmap.array.reshape(-1, nodes)          # also with 0 local cells


def entities_to_geometry(msh, dim, entities):
    """Geometry node indices of mesh entities."""
    if NEW_API:  # pragma: no cover
        from dolfinx import mesh as dmesh
        return dmesh.entities_to_geometry(msh, dim, entities, False)
    from dolfinx import cpp
    return cpp.mesh.entities_to_geometry(getattr(msh, "_mesh", msh), dim, entities, False)


def cell_tree(msh, cells, padding=0.0):
    """A bounding-box tree of the given local cells, each box grown by ``padding``."""
    tdim = msh.topology.dim
    cells = np.asarray(cells, dtype=np.int32)
    if NEW_API:  # pragma: no cover
        return geometry.bb_tree(msh, tdim, entities=cells, padding=padding)
    return geometry.BoundingBoxTree(msh, tdim, cells, padding)


def cell_candidates(tree, points):
    """For each point (rows of an (n, 3) array), the cells whose (padded) box contains it."""
    if NEW_API:  # pragma: no cover
        return geometry.compute_collisions_points(tree, points)
    return geometry.compute_collisions(tree, points)
