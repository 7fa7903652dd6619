"""The contact boundary Gamma_C of a Discretisation: the exterior facets whose vertices are all
constrained (the constrained boundary of ``Discretisation._boundary``, where the time series'
``gap_min_boundary`` looks), as a facet measure ds_C.

A treatment that integrates over the contact boundary (Nitsche's) needs every constrained
vertex on such a facet: a problem whose constrained vertices are inside the domain (the
membrane: the obstacle is under its whole surface) has none, and is refused in one line.
In 1-D the facets are the points at the ends of the interval.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.method.contact_boundary import CONTACT_TAG as CONTACT_TAG  # noqa: F401  (re-exported)
from sdm_dolfinx.method.contact_boundary import _facet_vertices, contact_facets as contact_facets, vertex_flag  # noqa: F401
from sdm_dolfinx.method.contact_boundary import contact_measure as contact_measure  # noqa: F401
from sdm_dolfinx.method.discretisation import vertex_coordinates, vertex_to_dof
from sdm_dolfinx.method.errors import DiscretisationError

def check_on_boundary(d, facets, what):
    """DiscretisationError (one line) when some constrained vertex lies on no contact facet."""
    msh = d.problem.mesh
    fv = _facet_vertices(msh)
    covered = vertex_flag(d, np.unique(fv[facets]) if len(facets) else np.zeros(0, dtype=np.int32))
    off = d.comm.allreduce(int(np.count_nonzero(covered[d.q1_of_c] <= 0)), op=MPI.SUM)
    if off:
        raise DiscretisationError(
            f"problem {d.problem.name!r}: {off} of its {d.num_constraints} constrained vertices are not on a "
            f"boundary facet whose vertices are all constrained, and {what} acts on the contact boundary; "
            f"use contact='exact' or contact='penalty'")


def cell_diameter(msh):
    """h_T as a DG0 Function: the largest distance between two vertices of each cell (UFL's
    CellDiameter of an affine simplex, which ffcx cannot evaluate on the disc's curved cells)."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    imap = msh.topology.index_map(tdim)
    ncells = imap.size_local + imap.num_ghosts
    c2v = msh.topology.connectivity(tdim, 0).array.reshape(-1, tdim + 1)[:ncells]
    x = vertex_coordinates(msh, c2v.reshape(-1)).T.reshape(ncells, tdim + 1, 3) if ncells else np.zeros((0, 1, 3))
    h = np.max(np.linalg.norm(x[:, :, None, :] - x[:, None, :, :], axis=-1), axis=(1, 2)) if ncells else np.zeros(0)
    V0 = compat.function_space(msh, compat.element("DG", compat.cell_name(msh), 0))
    f = fem.Function(V0)
    f.x.array[compat.dofmap_list(V0)[:ncells, 0]] = h
    return f


def facet_cell_dofs(d, facets):
    """The dofs of W^h on the cells of the contact ``facets``, Dirichlet dofs left out: where a
    boundary term over them reads u and puts its residual. Returns (their global indices, sorted,
    the same on every rank; this rank's owned ones as local indices). Collective."""
    msh, W = d.problem.mesh, d.W
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    cells = np.unique(np.concatenate([f2c.links(f) for f in facets])) if len(facets) else np.zeros(0, np.int32)
    blocks = np.unique(compat.dofmap_list(W)[cells].reshape(-1)) if len(cells) else np.zeros(0, np.int64)
    imap, bs = W.dofmap.index_map, W.dofmap.index_map_bs
    gblocks = np.asarray(imap.local_to_global(blocks.astype(np.int32)), dtype=np.int64)
    gdofs = (gblocks[:, None] * bs + np.arange(bs)[None, :]).reshape(-1)
    r0 = imap.local_range[0] * bs
    gdir = r0 + np.asarray(d.ddofs, dtype=np.int64)
    gall = np.unique(np.concatenate(d.comm.allgather(gdofs)))
    gall = gall[~np.isin(gall, np.concatenate(d.comm.allgather(gdir)))]
    mine = gall[(gall >= r0) & (gall < r0 + imap.size_local * bs)]
    return gall, (mine - r0).astype(np.int32)
