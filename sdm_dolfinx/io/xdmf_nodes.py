"""The nodes and cells of ``solution.xdmf`` in a partition-independent order, gathered on rank 0.

Two node sets (both give ``geometry``, ``topology`` and ``values(f)`` on rank 0):

* :class:`NodeOrder`: the mesh's own geometry nodes (vertices; on a curved quadratic mesh
  also its midside nodes), in the mesh's input order;
* :class:`EdgeNodes`: an affine mesh written as quadratic cells (``Edge_3``, ``Triangle_6``,
  ``Tetrahedron_10``) with straight edges, so that a P2 field shows its mid-edge values: the
  vertices in input order, then the edge midpoints ordered by their end vertices' input
  indices. Used when W^h is P2 on an affine mesh (a viewer otherwise never sees the mid-edge
  nodes of the contact boundary, which the vertex constraint does not hold).

:func:`output_nodes` chooses. Cells are written in a canonical order (sorted by their sorted
node numbers); :meth:`NodeOrder.cell_values` gathers a cell field (DG0) in that order.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx.mpiutil import gather_rows

#: XDMF topology names of (cell, degree), as dolfinx writes them
_XDMF_CELLS = {("triangle", 1): "Triangle", ("triangle", 2): "Triangle_6",
               ("quadrilateral", 1): "Quadrilateral", ("quadrilateral", 2): "Quadrilateral_9",
               ("tetrahedron", 1): "Tetrahedron", ("tetrahedron", 2): "Tetrahedron_10",
               ("hexahedron", 1): "Hexahedron", ("interval", 1): "PolyLine", ("interval", 2): "Edge_3"}

#: the edges of a simplex in VTK's order of the mid-edge nodes (Edge_3, Triangle_6, Tetrahedron_10)
_VTK_EDGES = {"interval": ((0, 1),), "triangle": ((0, 1), (1, 2), (2, 0)),
              "tetrahedron": ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))}


def geometry_columns(msh):
    """The coordinates written per point: the mesh's gdim, but 2 for an interval mesh (dolfinx
    0.5.2's XDMFFile writes its points as ``XY``, y = 0, and so do we)."""
    return max(int(msh.geometry.dim), 2)


def output_nodes(msh, w_degree):
    """The node set ``solution.xdmf`` is written on for displacements of Lagrange degree
    ``w_degree`` (None: not Lagrange, e.g. P1+).

    The mesh's own nodes, unless the mesh is affine (geometry degree 1), a simplex one, and the
    displacement is P2: then :class:`EdgeNodes` (P2 values at the mid-edge nodes).
    """
    degree = compat.geometry_degree(msh)
    if degree == 1 and w_degree == 2 and compat.cell_name(msh) in _VTK_EDGES:
        return EdgeNodes(msh)
    return NodeOrder(msh)


class _Order:
    """What both node sets share: the canonical cell order and the gathers."""

    def _finish(self, node_keys, cell_keys, x):
        """Rank 0: node order from the gathered node keys, topology from the cells' keys."""
        comm = self.comm
        self.num_nodes = comm.allreduce(len(node_keys), op=MPI.SUM)
        self.num_cells = comm.allreduce(len(cell_keys), op=MPI.SUM)
        all_keys, x, cells = gather_rows(node_keys, comm), gather_rows(x, comm), gather_rows(cell_keys, comm)
        self.order = self.geometry = self.topology = self.cell_order = None
        if comm.rank == 0:
            self.order = np.argsort(all_keys, kind="stable")
            ranked = all_keys[self.order]
            self.geometry = x[self.order]
            topo = np.searchsorted(ranked, cells).astype(np.int64)
            key_rows = np.sort(topo, axis=1)
            self.cell_order = np.lexsort(key_rows.T[::-1]) if len(topo) else np.arange(0)
            self.topology = topo[self.cell_order]

    def _gather(self, rows):
        vals = gather_rows(rows, self.comm)
        return vals[self.order] if self.comm.rank == 0 else None

    def cell_values(self, f):
        """The values (cells, components) of a DG0 function ``f`` in the written cell order on
        rank 0 (None elsewhere)."""
        V = f.function_space
        bs = V.dofmap.index_map_bs
        dofs = compat.dofmap_list(V)[:self.ncells, 0]
        vals = gather_rows(np.asarray(f.x.array).reshape(-1, bs)[dofs], self.comm)
        return vals[self.cell_order] if self.comm.rank == 0 else None


class NodeOrder(_Order):
    """The mesh's geometry nodes in their input order (partition-independent) and the cells in
    a canonical order, gathered on rank 0; :meth:`values` gathers a field's nodal values in
    that order.

    The field's space must be Lagrange of the geometry's degree: its k-th cell dof is then
    the k-th geometry node of the cell (checked by coordinates)."""

    def __init__(self, msh):
        self.comm = msh.comm
        geo = msh.geometry
        self.gdim, tdim = geometry_columns(msh), msh.topology.dim
        self.nloc = nloc = geo.index_map().size_local
        inputs = np.asarray(geo.input_global_indices, dtype=np.int64)
        gdm = compat.mesh_geometry_dofmap(msh)
        self.ncells = msh.topology.index_map(tdim).size_local
        nodes = gdm.shape[1]
        from dolfinx.cpp.io import perm_vtk
        perm = np.argsort(np.asarray(perm_vtk(msh.topology.cell_type, nodes)))
        self.gdm, self.nodes = gdm, nodes
        self.cell_name = compat.cell_name(msh)
        self.degree = compat.geometry_degree(msh)
        key = (self.cell_name, self.degree)
        if key not in _XDMF_CELLS:
            raise NotImplementedError(f"XDMF output of {self.cell_name} cells of degree {self.degree}")
        self.topology_type = _XDMF_CELLS[key]
        self._dof_of_node = {}
        self._finish(inputs[:nloc], inputs[gdm[:self.ncells]][:, perm].reshape(-1, nodes),
                     np.asarray(geo.x[:nloc, :self.gdim]))

    def dof_of_node(self, V):
        """For the local nodes, the dof (block) of V at that node."""
        key = id(V)
        if key not in self._dof_of_node:
            dofs = compat.dofmap_list(V)
            m = np.full(self.gdm.max(initial=-1) + 1, -1, dtype=np.int64)
            m[self.gdm.reshape(-1)] = dofs.reshape(-1)
            xdof = V.tabulate_dof_coordinates()[m[:self.nloc]]
            xnode = V.mesh.geometry.x[:self.nloc]
            scale = max(float(np.abs(xnode).max(initial=0.0)), 1.0)
            if self.comm.allreduce(bool(len(xdof) and np.abs(xdof - xnode).max() > 1e-9 * scale), op=MPI.LOR):
                raise RuntimeError("the output space's dofs are not at the mesh's geometry nodes")
            self._dof_of_node[key] = m
        return self._dof_of_node[key]

    def values(self, f):
        """The nodal values of ``f`` (n, components) in input order on rank 0 (None elsewhere)."""
        V = f.function_space
        bs = V.dofmap.index_map_bs
        m = self.dof_of_node(V)[:self.nloc]
        return self._gather(np.asarray(f.x.array).reshape(-1, bs)[m])


class EdgeNodes(_Order):
    """An affine simplex mesh as quadratic cells with straight edges: the nodes are the dofs of
    P2 Lagrange (vertices, then edge midpoints), keyed by the input indices of their vertices
    (a vertex v: (v, v); an edge: its two ends, smaller first), so the file does not depend on
    the partition. :meth:`values` takes a function in a P2 Lagrange space on the mesh
    (:attr:`degree` 2: the writer interpolates every field into one)."""

    degree = 2

    def __init__(self, msh):
        self.comm = msh.comm
        geo = msh.geometry
        self.gdim, tdim = geometry_columns(msh), msh.topology.dim
        self.cell_name = compat.cell_name(msh)
        self.topology_type = _XDMF_CELLS[(self.cell_name, 2)]
        edges = _VTK_EDGES[self.cell_name]
        nv = tdim + 1
        self.nodes = nv + len(edges)
        self.ncells = msh.topology.index_map(tdim).size_local
        inputs = np.asarray(geo.input_global_indices, dtype=np.int64)
        self.big = big = int(self.comm.allreduce(int(inputs.max(initial=-1)), op=MPI.MAX)) + 1
        gdm = compat.mesh_geometry_dofmap(msh)
        vin = inputs[gdm]                                   # (all local cells, nv)
        pairs = np.array(edges)
        a, b = vin[:, pairs[:, 0]], vin[:, pairs[:, 1]]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        cell_keys = np.hstack([vin * (big + 1), big * big + lo * big + hi])        # (cells, nodes)
        xv = geo.x[gdm]                                                            # (cells, nv, 3)
        cand_x = np.concatenate([xv, 0.5 * (xv[:, pairs[:, 0]] + xv[:, pairs[:, 1]])], axis=1)
        self.V2 = compat.function_space(msh, compat.element("Lagrange", self.cell_name, 2))
        dofs = compat.dofmap_list(self.V2)
        xd = self.V2.tabulate_dof_coordinates()
        # each cell dof of P2 is one candidate node (a vertex or an edge midpoint) of its cell
        dist = np.linalg.norm(xd[dofs][:, :, None, :] - cand_x[:, None, :, :], axis=3)
        which = np.argmin(dist, axis=2)
        scale = max(float(np.abs(geo.x).max(initial=0.0)), 1.0)
        bad = bool(dist.size and np.take_along_axis(dist, which[:, :, None], 2).max() > 1e-9 * scale)
        if self.comm.allreduce(bad, op=MPI.LOR):
            raise RuntimeError("P2 dofs that are not at the vertices and edge midpoints of their cells")
        key_of_dof = np.empty(xd.shape[0], dtype=np.int64)
        key_of_dof[dofs.reshape(-1)] = np.take_along_axis(cell_keys, which, 1).reshape(-1)
        self.nloc = self.V2.dofmap.index_map.size_local
        self._dofs = {}
        self._finish(key_of_dof[:self.nloc], cell_keys[:self.ncells], np.asarray(xd[:self.nloc, :self.gdim]))

    def values(self, f):
        """The nodal values of ``f`` (a P2 Lagrange function on the mesh) on rank 0 (None elsewhere)."""
        V = f.function_space
        if id(V) not in self._dofs:            # V's dof of each node of V2 (same cell layout)
            m = np.empty(self.V2.tabulate_dof_coordinates().shape[0], dtype=np.int64)
            m[compat.dofmap_list(self.V2).reshape(-1)] = compat.dofmap_list(V).reshape(-1)
            self._dofs[id(V)] = m[:self.nloc]
        bs = V.dofmap.index_map_bs
        return self._gather(np.asarray(f.x.array).reshape(-1, bs)[self._dofs[id(V)]])
