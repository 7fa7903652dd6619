"""The contact boundary Gamma_C of a Discretisation: the exterior facets whose vertices are all
constrained (where the time series' ``gap_min_boundary`` looks), and a facet measure ds_C on them:
where a weighted gap (:mod:`.weighted_rows`) and the Nitsche treatment integrate. In 1-D the
facets are the points at the ends of the interval.
"""
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.method.dofs import vertex_to_dof
from sdm_dolfinx.problems.contact_pairs import constrained_vertices


#: the meshtags value of the contact facets
CONTACT_TAG = 1


def vertex_flag(d, vertices):
    """1.0 at the Q1 dofs of the local ``vertices`` on any rank, consistent on ghosts."""
    flag = fem.Function(d.Q1)
    if len(vertices):
        flag.x.array[vertex_to_dof(d.Q1, vertices)] = 1.0
    vec = compat.petsc_vec(flag)
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    return flag.x.array


def _facet_vertices(msh):
    """(local facets, their vertices) as an array of shape (n_facets, vertices per facet)."""
    tdim = msh.topology.dim
    fdim = tdim - 1
    msh.topology.create_connectivity(fdim, 0)
    msh.topology.create_connectivity(fdim, tdim)
    return msh.topology.connectivity(fdim, 0).array.reshape(-1, max(tdim, 1))


def contact_facets(d):
    """The local exterior facets whose vertices are all constrained (sorted)."""
    msh = d.problem.mesh
    fv = _facet_vertices(msh)
    nv = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    marked = vertex_flag(d, constrained_vertices(d.problem, msh))
    all_marked = np.all(marked[vertex_to_dof(d.Q1, np.arange(nv))[fv]] > 0, axis=1)
    exterior = np.asarray(dmesh.exterior_facet_indices(msh.topology), dtype=np.int32)
    return np.sort(exterior[all_marked[exterior]]).astype(np.int32)


def contact_measure(d, facets, degree):
    """ds over the contact facets with quadrature ``degree`` (every integral of a treatment uses
    the same rule, so that its discrete identities hold point by point)."""
    msh = d.problem.mesh
    tags = dmesh.meshtags(msh, msh.topology.dim - 1, facets, np.full(len(facets), CONTACT_TAG, dtype=np.int32))
    return ufl.Measure("ds", domain=msh, subdomain_data=tags,
                       metadata={"quadrature_degree": int(degree)})(CONTACT_TAG)
