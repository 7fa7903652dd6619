"""solution.xdmf + solution.h5, written by rank 0 in dolfinx's layout and in a partition-
independent order (see :class:`XDMFWriter`); imported by :mod:`.observers`."""
import os
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
from dolfinx import fem

from sdm_dolfinx import compat
from sdm_dolfinx.mpiutil import atomic_write_text, gather_rows
from sdm_dolfinx.run.journal import FileVanished


def match_rows(saved, mine, what):
    """Index into ``mine`` of each row of ``saved`` (both (n, 3) coordinates of the same points
    in two orders), or raise ValueError."""
    if saved.shape == mine.shape and np.array_equal(saved, mine):
        return None                                 # same order: nothing to map
    from scipy.spatial import cKDTree
    scale = max(float(np.abs(mine).max(initial=0.0)), 1.0)
    if len(saved) != len(mine):
        raise ValueError(f"{what}: {len(saved)} points in the file, {len(mine)} in this run")
    d, idx = cKDTree(mine).query(saved)
    if len(idx) and (d.max() > 1e-9 * scale or len(np.unique(idx)) != len(idx)):
        raise ValueError(f"{what}: the points stored in the file are not this run's")
    return idx


#: XDMF topology names of (cell, geometry degree), as dolfinx writes them
_XDMF_CELLS = {("triangle", 1): "Triangle", ("triangle", 2): "Triangle_6",
               ("quadrilateral", 1): "Quadrilateral", ("quadrilateral", 2): "Quadrilateral_9",
               ("tetrahedron", 1): "Tetrahedron", ("tetrahedron", 2): "Tetrahedron_10",
               ("hexahedron", 1): "Hexahedron", ("interval", 1): "PolyLine"}
_XINCLUDE = ("<xi:include xpointer=\"xpointer(/Xdmf/Domain/Grid[@GridType='Uniform'][1]/*[self::Topology or "
             "self::Geometry])\" />")


def time_key(t):
    """A time as dolfinx's XDMF writes it (17 significant digits), and its HDF5 dataset name."""
    text = "%.17g" % float(t)
    return text, text.replace(".", "_")


class _NodeOrder:
    """The mesh's geometry nodes in their input order (partition-independent) and the cells in
    a canonical order, gathered on rank 0; :meth:`values` gathers a field's nodal values in
    that order.

    The field's space must be Lagrange of the geometry's degree: its k-th cell dof is then
    the k-th geometry node of the cell (checked by coordinates)."""

    def __init__(self, msh):
        self.comm = comm = msh.comm
        geo = msh.geometry
        self.gdim, tdim = geo.dim, msh.topology.dim
        nloc = geo.index_map().size_local
        self.nloc = nloc
        inputs = np.asarray(geo.input_global_indices, dtype=np.int64)
        gdm = compat.mesh_geometry_dofmap(msh)
        ncells = msh.topology.index_map(tdim).size_local
        nodes = gdm.shape[1]
        from dolfinx.cpp.io import perm_vtk
        perm = np.argsort(np.asarray(perm_vtk(msh.topology.cell_type, nodes)))
        all_inputs = gather_rows(inputs[:nloc], comm)
        x = gather_rows(np.asarray(geo.x[:nloc, :self.gdim]), comm)
        cells = gather_rows(inputs[gdm[:ncells]][:, perm].reshape(-1, nodes), comm)
        self.gdm, self.nodes = gdm, nodes
        self.cell_name = compat.cell_name(msh)
        self.degree = int(geo.cmap.degree)
        key = (self.cell_name, self.degree)
        if key not in _XDMF_CELLS:
            raise NotImplementedError(f"XDMF output of {self.cell_name} cells of degree {self.degree}")
        self.topology_type = _XDMF_CELLS[key]
        self.num_nodes = comm.allreduce(nloc, op=MPI.SUM)
        self.num_cells = comm.allreduce(ncells, op=MPI.SUM)
        self._dof_of_node = {}
        self.order = self.geometry = self.topology = None
        if comm.rank == 0:
            self.order = np.argsort(all_inputs, kind="stable")
            ranked = all_inputs[self.order]
            self.geometry = x[self.order]
            topo = np.searchsorted(ranked, cells).astype(np.int64)
            key_rows = np.sort(topo, axis=1)
            self.topology = topo[np.lexsort(key_rows.T[::-1])] if len(topo) else topo

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
        vals = gather_rows(np.asarray(f.x.array).reshape(-1, bs)[m], self.comm)
        return vals[self.order] if self.comm.rank == 0 else None


class XDMFWriter:
    """solution.xdmf + solution.h5: displacement, velocity, contact stress and active set at
    the mesh's nodes, in dolfinx's layout (ParaView and :func:`sdm_dolfinx.post.xdmf.read_xdmf`
    read it as before).

    The fields are explicit P1 interpolants (on a curved quadratic mesh, interpolated again
    to its geometry nodes, so midside nodes carry the average of their vertices). Rank 0
    writes them after a gather, in the mesh's input node order (the same file on any
    number of ranks); the HDF5 file through its :class:`JournaledFile`, then the whole XML
    atomically (it lists only steps whose data is complete).

    Args:
        journal: the HDF5 file's :class:`JournaledFile` (rank 0; None elsewhere).
        steps: None for new files; else the steps already in the HDF5 file (a restart).
    """

    FIELDS = ("displacement", "velocity", "contact_stress", "active")

    def __init__(self, path, discretisation, integrator, dt, journal=None, steps=None):
        self.discretisation, self.integ, self.dt = discretisation, integrator, dt
        msh = discretisation.problem.mesh
        self.path, self.comm, self.journal = Path(path), msh.comm, journal
        self.h5name = self.path.with_suffix(".h5").name
        self.nodes = _NodeOrder(msh)
        self.uW = fem.Function(discretisation.W)
        self.vsrc = fem.Function(discretisation.H if integrator.block else discretisation.W)
        self.u1 = fem.Function(discretisation.P1, name="displacement")
        self.v1 = fem.Function(discretisation.P1, name="velocity")
        self.s1 = fem.Function(discretisation.Q1, name="contact_stress")
        self.a1 = fem.Function(discretisation.Q1, name="active")
        self.out = {}                   # P1 field -> the geometry-degree Function written
        for f in (self.u1, self.v1, self.s1, self.a1):
            self.out[f.name] = f
            if self.nodes.degree != 1:
                shape = f.ufl_shape
                G = compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), self.nodes.degree,
                                                              shape))
                self.out[f.name] = fem.Function(G, name=f.name)
        self.vector = len(self.u1.ufl_shape) > 0
        self.map = None
        self.steps = list(steps or [])
        self.xml_inode = None
        self._grids = {}
        if self.comm.rank != 0:
            return
        if steps is None:
            with journal.h5("w") as h5:
                h5.create_dataset("Mesh/mesh/geometry", data=self.nodes.geometry)
                h5.create_dataset("Mesh/mesh/topology", data=self.nodes.topology)
        else:
            with journal.h5("r") as h5:
                self.map = match_rows(pad3(np.asarray(h5["Mesh/mesh/geometry"])), pad3(self.nodes.geometry),
                                       f"{self.path.with_suffix('.h5')} (mesh)")
                missing = [name for n in self.steps for name in self._datasets(n) if name not in h5]
                if missing:
                    raise ValueError(f"{self.path.with_suffix('.h5')}: {missing[0]} is missing")
            self._write_xml(replace_any=True)

    def _datasets(self, n):
        key = time_key(n * self.dt)[1]
        return [f"Function/{name}/{key}" for name in self.FIELDS]

    def write(self, U, V, lam, active, n):
        """Write the displacement, velocity, contact stress and active set of step ``n`` (collective).

        The fields are interpolated into P1 (vertex values) so that dolfinx 0.5 and 0.10 write the same file;
        the contact stress is each constrained vertex's multiplier divided by its lumped measure.
        """
        d = self.discretisation
        self.uW.x.array[:len(U.array)] = U.array
        self.uW.x.scatter_forward()
        self.u1.interpolate(self.uW)
        self.vsrc.x.array[:len(V.array)] = V.array
        self.vsrc.x.scatter_forward()
        self.v1.interpolate(self.vsrc)
        for f, vals in ((self.s1, lam / np.where(d.cmeasure > 0, d.cmeasure, 1.0)),
                        (self.a1, active.astype(float))):
            f.x.array[:] = 0.0
            f.x.array[d.q1_of_c] = vals
            vec = compat.petsc_vec(f)
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        data = {}
        for f in (self.u1, self.v1, self.s1, self.a1):
            g = self.out[f.name]
            if g is not f:
                g.interpolate(f)
                g.x.scatter_forward()
            vals = self.nodes.values(g)
            if self.comm.rank == 0:
                if vals.shape[1] > 1:           # vectors padded to 3 components, as dolfinx does
                    vals = pad3(vals)
                data[f.name] = vals if self.map is None else vals[self.map]
        if self.comm.rank == 0:
            names = self._datasets(n)
            with self.journal.h5() as h5:
                for name, f in zip(names, self.FIELDS):
                    if name in h5:              # the failed-step write of a step written already
                        del h5[name]
                    h5.create_dataset(name, data=data[f])
            if n not in self.steps:
                self.steps.append(n)
            self._write_xml()

    def _write_xml(self, replace_any=False):
        """The whole XML, atomically (rank 0); a file deleted or replaced by someone else since
        the last write is reported (:class:`FileVanished`)."""
        if not replace_any and self.xml_inode is not None:
            try:
                if os.stat(self.path).st_ino != self.xml_inode:
                    raise FileVanished(self.path)
            except FileNotFoundError:
                raise FileVanished(self.path) from None
        atomic_write_text(self.path, self.xml())
        self.xml_inode = os.stat(self.path).st_ino

    def xml(self):
        """The XML text of the steps written so far (dolfinx's layout, byte for byte)."""
        nn, nc, h5 = self.nodes.num_nodes, self.nodes.num_cells, self.h5name
        ind = "  "
        lines = ['<?xml version="1.0"?>', '<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">',
                 f"{ind}<Domain>", f'{ind * 2}<Grid Name="mesh" GridType="Uniform">',
                 f'{ind * 3}<Topology TopologyType="{self.nodes.topology_type}" NumberOfElements="{nc}" '
                 f'NodesPerElement="{self.nodes.nodes}">',
                 f'{ind * 4}<DataItem Dimensions="{nc} {self.nodes.nodes}" NumberType="Int" Format="HDF">'
                 f'{h5}:/Mesh/mesh/topology</DataItem>',
                 f"{ind * 3}</Topology>",
                 f'{ind * 3}<Geometry GeometryType="{"XY" if self.nodes.gdim == 2 else "XYZ"}">',
                 f'{ind * 4}<DataItem Dimensions="{nn} {self.nodes.gdim}" Format="HDF">{h5}:/Mesh/mesh/geometry'
                 f'</DataItem>',
                 f"{ind * 3}</Geometry>", f"{ind * 2}</Grid>"]
        steps = sorted(self.steps)
        for name in self.FIELDS:
            if not steps:
                break
            lines.append(f'{ind * 2}<Grid Name="{name}" GridType="Collection" CollectionType="Temporal">')
            lines += [self._grid(name, n) for n in steps]
            lines.append(f"{ind * 2}</Grid>")
        lines += [f"{ind}</Domain>", "</Xdmf>"]
        return "\n".join(lines) + "\n"

    def _grid(self, name, n):
        """The XML of field ``name`` at step ``n`` (made once)."""
        key = (name, n)
        if key not in self._grids:
            ind, nn = "  ", self.nodes.num_nodes
            vector = self.vector and name in ("displacement", "velocity")
            text, tkey = time_key(n * self.dt)
            self._grids[key] = "\n".join([
                f'{ind * 3}<Grid Name="{name}" GridType="Uniform">', f"{ind * 4}{_XINCLUDE}",
                f'{ind * 4}<Time Value="{text}" />',
                f'{ind * 4}<Attribute Name="{name}" AttributeType="{"Vector" if vector else "Scalar"}" Center="Node">',
                f'{ind * 5}<DataItem Dimensions="{nn} {3 if vector else 1}" Format="HDF">'
                f'{self.h5name}:/Function/{name}/{tkey}</DataItem>',
                f"{ind * 4}</Attribute>", f"{ind * 3}</Grid>"])
        return self._grids[key]


def pad3(a):
    """Rows of 1, 2 or 3 components padded to 3 (as dolfinx writes vectors and points)."""
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        a = a[:, None]
    out = np.zeros((a.shape[0], 3))
    out[:, :a.shape[1]] = a
    return out
