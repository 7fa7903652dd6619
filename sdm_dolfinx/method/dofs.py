"""Where a space's dofs are: the dof of each mesh vertex, vertex coordinates, the owned size, the point where
a distributed minimum is reached."""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat


def vertex_to_dof(V, vertices):
    """Local (unblocked) dof index of V at each local mesh vertex in ``vertices``.

    Uses the element's vertex entity dofs, so it works for P1, P2 and P1+bubble alike.
    """
    msh = V.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    c2v = msh.topology.connectivity(tdim, 0)
    nv_cell = tdim + 1                                      # simplices (intervals, triangles, tetrahedra)
    cell_vertices = c2v.array.reshape(-1, nv_cell)          # (also on a rank without cells)
    dofs = compat.dofmap_list(V)
    nverts = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    v2d = np.full(nverts, -1, dtype=np.int64)
    layout = V.dofmap.dof_layout
    for k in range(cell_vertices.shape[1]):
        (ldof,) = layout.entity_dofs(0, k)
        v2d[cell_vertices[:, k]] = dofs[:, ldof]
    return v2d[np.asarray(vertices, dtype=np.int64)]


def vertex_coordinates(msh, vertices):
    """Coordinates (3, n) of local mesh vertices (via the geometry of P1/P2 meshes)."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(0, tdim)
    nodes = compat.entities_to_geometry(msh, 0, np.asarray(vertices, dtype=np.int32))
    return msh.geometry.x[nodes.reshape(-1)].T


def owned_size(V):
    """Number of owned entries (dofs times block size) of V's vectors on this rank."""
    return V.dofmap.index_map.size_local * V.dofmap.index_map_bs


def where_least(comm, values, x):
    """The column of ``x`` (3, n) at this rank's least of ``values`` (n,) that is the least over the ranks,
    on every rank (collective; ties to the lowest rank)."""
    k = int(np.argmin(values)) if values.size else -1
    _, owner = comm.allreduce((float(values[k]) if k >= 0 else np.inf, comm.rank), op=MPI.MINLOC)
    return np.asarray(comm.bcast(x[:, k] if comm.rank == owner else None, root=owner))


def reference_positions(W):
    """The owned coefficients of the identity x -> x interpolated into the vector space W (the reference
    positions of its nodes; 0 at a bubble's dof, whose field the identity does not need)."""
    from dolfinx import fem
    gdim = W.mesh.geometry.dim
    f = fem.Function(W)
    f.interpolate(lambda x: x[:gdim])
    return f.x.array[:owned_size(W)].copy()
