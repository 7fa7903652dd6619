"""solution.xdmf + solution.h5, written by rank 0 in dolfinx's layout and in a partition-
independent order (see :class:`XDMFWriter`); imported by :mod:`.run_files`."""
import os
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
from dolfinx import fem

from sdm_dolfinx import compat
from sdm_dolfinx.contact.friction import tangential_axes
from sdm_dolfinx.method.discretisation import vertex_to_dof
from sdm_dolfinx.mpiutil import atomic_write_text
from sdm_dolfinx.io.journal import FileVanished
from sdm_dolfinx.io.xdmf_nodes import output_nodes


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


def match_cells(saved, mine, node_map, what):
    """Index into ``mine`` (cells as node numbers of this run) of each cell of ``saved`` (the
    file's, in the file's node numbers; ``node_map[i]``: this run's node of the file's node i),
    or raise ValueError: the cell values of a restart go in the file's cell order."""
    inverse = np.empty(len(node_map), dtype=np.int64)
    inverse[node_map] = np.arange(len(node_map))
    index = {tuple(sorted(c)): k for k, c in enumerate(inverse[mine])}
    try:
        return np.array([index[tuple(sorted(c))] for c in saved], dtype=np.int64)
    except KeyError:
        raise ValueError(f"{what}: the cells stored in the file are not this run's") from None


_XINCLUDE = ("<xi:include xpointer=\"xpointer(/Xdmf/Domain/Grid[@GridType='Uniform'][1]/*[self::Topology or "
             "self::Geometry])\" />")


#: the fields a run may write, in the order of the files (each run writes those that apply to it)
FIELD_ORDER = ("displacement", "velocity", "Vbar_W", "contact_stress", "active", "tangential_stress",
               "contact_status", "body")


def body_tag(d):
    """A DG0 Function numbering each cell's body: k for the cells of ``d.problem.bodies[k - 1]``, 0 for the
    cells of none (run.json's ``problem.bodies`` names them in this order)."""
    msh = d.problem.mesh
    tag = fem.Function(compat.function_space(msh, compat.element("DG", compat.cell_name(msh), 0)))
    dofs = compat.dofmap_list(tag.function_space)[:, 0]
    for k, body in enumerate(d.problem.bodies, start=1):
        cells = np.asarray(body.cells(msh), dtype=np.int64).reshape(-1)
        tag.x.array[dofs[cells]] = float(k)
    return tag


def time_key(t):
    """A time as dolfinx's XDMF writes it (17 significant digits), and its HDF5 dataset name."""
    text = "%.17g" % float(t)
    return text, text.replace(".", "_")


class XDMFWriter:
    """solution.xdmf + solution.h5: the fields of every K-th step in dolfinx's layout (ParaView
    and :func:`sdm_dolfinx.io.xdmf_reader.read_xdmf` read it).

    Fields (docs/outputs.md): ``displacement`` (U^{n+1}), ``velocity`` (the physical velocity:
    the SDM velocity in H^h, C^-1 B Vbar, or V of the (U, V) system; Vbar itself for the
    standard method, where H^h = W^h), ``Vbar_W`` (only when H^h differs from W^h in the M
    formulation: the W^h vector Vbar whose Ker(B) part is arbitrary, not a velocity),
    ``contact_stress`` and ``active``; with the Problem's ``bodies`` the cell field ``body`` (k on the cells
    of the k-th body, 0 elsewhere: :func:`body_tag`). A P0 velocity is written per cell, the rest at the nodes
    of :func:`~sdm_dolfinx.io.xdmf_nodes.output_nodes`: the mesh's own (on a curved quadratic
    mesh its midside nodes too), or, for a P2 displacement on an affine mesh, the mesh as
    straight quadratic cells, so that the mid-edge values of P2 fields are seen. A field whose
    space is Lagrange of degree <= the nodes' degree is written exactly; others (P1+) through
    their vertex values. An interval mesh is written as dolfinx 0.5.2 writes one: ``PolyLine``
    cells (``Edge_3`` with the mid-edge nodes of a P2 displacement) and ``XY`` points (y = 0).
    Rank 0 writes after a gather, in a partition-independent order (the
    same file on any number of ranks); the HDF5 file through its :class:`JournaledFile`, then
    the whole XML atomically (it lists only steps whose data is complete).

    Args:
        block: V is the (U, V) block system's velocity in H^h (mass ``"consistent"``), else Vbar in W^h.
        friction: write the friction fields ``tangential_stress`` and ``contact_status`` (then
            :meth:`write` takes the step's ``lam_t`` and ``slipping``); in 3-D ``tangential_stress``
            is a vector (its components along the tangential axes, 0 along the normal).
        journal: the HDF5 file's :class:`JournaledFile` (rank 0; None elsewhere).
        steps: None for new files; else the steps already in the HDF5 file (a restart).
    """

    def __init__(self, path, discretisation, dt, block=False, friction=False, journal=None, steps=None):
        self.discretisation, self.dt, self.block = discretisation, dt, bool(block)
        d = discretisation
        msh = d.problem.mesh
        self.path, self.comm, self.journal = Path(path), msh.comm, journal
        self.h5name = self.path.with_suffix(".h5").name
        wdeg = d.pair.w[1] if d.pair.w[0] == "P" else None
        self.nodes = output_nodes(msh, wdeg)
        self.vector = bool(d.problem.shape)
        self.uW = fem.Function(d.W)
        self.vH = fem.Function(d.H) if d.H is not None else None
        self.vW = fem.Function(d.W) if not self.block else None
        self._vH_vec = d.B.createVecLeft() if self.vH is not None and self.vW is not None else None
        self.s1, self.a1 = fem.Function(d.Q1), fem.Function(d.Q1)
        # name -> (source Function, its Lagrange degree: 0 = P0 (written per cell), None = other)
        pair = d.pair
        vel = (self.vH, pair.h[1]) if self.vH is not None else (self.vW, wdeg)
        src = {"displacement": (self.uW, wdeg), "velocity": vel, "contact_stress": (self.s1, 1), "active": (self.a1, 1)}
        if self.vH is not None and self.vW is not None:
            src["Vbar_W"] = (self.vW, wdeg)
        self.friction = bool(friction)
        #: the tangential axes of a 3-D problem's friction (its tangential_stress is then a vector)
        self.tangent = tangential_axes(d.problem) if self.friction and len(tangential_axes(d.problem)) > 1 else ()
        if self.friction:                           # lam_T / m_i and 0 free, 1 stick, 2 slip
            stress = fem.Function(d.P1 if self.tangent else d.Q1)
            src["tangential_stress"], src["contact_status"] = (stress, 1), (fem.Function(d.Q1), 1)
            if self.tangent:                        # the constrained vertices' blocks in the vector P1 space
                self._p1_of_c = vertex_to_dof(d.P1, d.cverts[d.c_vertex])
        if getattr(d.problem, "bodies", None):     # the cells' body: 1, 2, ... in the order of ``bodies``
            src["body"] = (body_tag(d), 0)
        self.vector_fields = ({"displacement", "velocity", "Vbar_W"} if self.vector else set()) | (
            {"tangential_stress"} if self.tangent else set())
        self.FIELDS = tuple(n for n in FIELD_ORDER if n in src)
        self.src = {n: f for n, (f, _) in src.items()}
        self.cell_fields = {n for n, (_, k) in src.items() if k == 0}
        self._spaces = {}
        self.out = {n: self._route(f, k) for n, (f, k) in src.items() if k != 0}
        self.map = self.cell_map = None
        self.steps = list(steps or [])
        self.xml_inode = None
        self._grids = {}
        if "body" in self.FIELDS and self.steps:    # a run written before the field existed goes on without it
            older = None
            if self.comm.rank == 0:
                with journal.h5("r") as h5:
                    older = "Function/body" not in h5
            if self.comm.bcast(older, root=0):
                self.FIELDS = tuple(n for n in self.FIELDS if n != "body")
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
                if self.map is not None and self.cell_fields:
                    self.cell_map = match_cells(np.asarray(h5["Mesh/mesh/topology"]), self.nodes.topology, self.map,
                                                f"{self.path.with_suffix('.h5')} (cells)")
                missing = [name for n in self.steps for name in self._datasets(n) if name not in h5]
                if missing:
                    raise ValueError(f"{self.path.with_suffix('.h5')}: {missing[0]} is missing (written by an "
                                     f"older version or damaged)")
            self._write_xml(replace_any=True)

    def _route(self, f, degree):
        """(Function on the output nodes or None: f's own P1, P1 interpolant on the way or None).

        A Lagrange field of degree <= the nodes' is interpolated exactly; another (P1+) through
        its vertex values."""
        d, deg = self.discretisation, self.nodes.degree
        shape = f.ufl_shape
        exact = degree is not None and degree <= deg
        via = None if exact else fem.Function(d.P1 if shape else d.Q1)
        if deg == 1:                           # the mesh's vertices: f itself (P1) or its P1 interpolant
            return None, via
        if shape not in self._spaces:          # one Lagrange space of the nodes' degree per value shape
            msh = d.problem.mesh
            self._spaces[shape] = compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), deg,
                                                                            shape))
        return fem.Function(self._spaces[shape]), via

    def _datasets(self, n):
        key = time_key(n * self.dt)[1]
        return [f"Function/{name}/{key}" for name in self.FIELDS]

    def _fill(self, U, V, lam, active, lam_t, slipping):
        """The source functions of the fields from the step's vectors (collective)."""
        d = self.discretisation
        self.uW.x.array[:len(U.array)] = U.array
        if self.block:
            self.vH.x.array[:len(V.array)] = V.array
        else:
            self.vW.x.array[:len(V.array)] = V.array
            if self.vH is not None:                 # the physical velocity C^-1 B Vbar
                h = d.physical_velocity(V, self._vH_vec)
                self.vH.x.array[:len(h.array)] = h.array
        for f in (self.uW, self.vH, self.vW):
            if f is not None:
                f.x.scatter_forward()
        measure = np.where(d.cmeasure > 0, d.cmeasure, 1.0)
        vertex = [(self.s1, lam / measure), (self.a1, active.astype(float))]
        if self.friction:                           # 0 not in contact, 1 sticking, 2 slipping
            status = np.where(active, np.where(np.asarray(slipping, dtype=bool), 2.0, 1.0), 0.0)
            vertex.append((self.src["contact_status"], status))
            if self.tangent:
                self._fill_tangential(np.asarray(lam_t) / measure[:, None])
            else:
                vertex.append((self.src["tangential_stress"], lam_t / measure))
        for f, vals in vertex:
            f.x.array[:] = 0.0
            f.x.array[d.q1_of_c] = np.asarray(vals)[d.c_vertex]     # constrain="nodes": the vertex dofs
            vec = compat.petsc_vec(f)
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)

    def _fill_tangential(self, tau):
        """3-D: the vector tangential_stress from its components ``tau`` (m x 2, along the tangential
        axes) at the owned constrained vertices, 0 along the normal and elsewhere (collective)."""
        d, f = self.discretisation, self.src["tangential_stress"]
        bs = d.P1.dofmap.index_map_bs
        f.x.array[:] = 0.0
        for k, axis in enumerate(self.tangent):
            f.x.array[self._p1_of_c * bs + axis] = tau[d.c_vertex, k]
        vec = compat.petsc_vec(f)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)

    def _values(self, name):
        """The rows of field ``name`` on rank 0 (None elsewhere), vectors padded to 3 (collective)."""
        f = self.src[name]
        if name in self.cell_fields:
            vals = self.nodes.cell_values(f)
        else:
            out, via = self.out[name]
            if via is not None:
                via.interpolate(f)
                f = via
            if out is not None:
                out.interpolate(f)
                out.x.scatter_forward()
                f = out
            vals = self.nodes.values(f)
        if self.comm.rank != 0:
            return None
        if vals.shape[1] > 1:                   # vectors padded to 3 components, as dolfinx does
            vals = pad3(vals)
        order = self.cell_map if name in self.cell_fields else self.map
        return vals if order is None else vals[order]

    def write(self, U, V, lam, active, n, lam_t=None, slipping=None):
        """Write the fields of step ``n`` (collective); the contact stress is each constrained
        vertex's multiplier divided by its lumped measure. With friction, ``lam_t`` (the tangential
        multipliers, signed: m in 2-D, m x 2 in 3-D) and ``slipping`` (the slip set) at the owned
        constrained vertices."""
        if (lam_t is not None, slipping is not None) != (self.friction, self.friction):
            raise TypeError("XDMFWriter.write takes lam_t and slipping exactly when it writes the friction fields")
        self._fill(U, V, lam, active, lam_t, slipping)
        data = {name: self._values(name) for name in self.FIELDS}
        if self.comm.rank == 0:
            names = self._datasets(n)
            with self.journal.h5() as h5:
                for name, f in zip(names, self.FIELDS):
                    if name in h5:              # the failed-step write of a step written already
                        del h5[name]
                    h5.create_dataset(name, data=data[f])
            added = n not in self.steps
            if added:
                self.steps.append(n)
            try:
                self._write_xml()
            except BaseException:
                if added:                       # the XML lists the steps before it: so must the file
                    self.steps.remove(n)
                self.journal.undo_last()
                raise

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
            vector = name in self.vector_fields
            centre, rows = ("Cell", self.nodes.num_cells) if name in self.cell_fields else ("Node", nn)
            text, tkey = time_key(n * self.dt)
            self._grids[key] = "\n".join([
                f'{ind * 3}<Grid Name="{name}" GridType="Uniform">', f"{ind * 4}{_XINCLUDE}",
                f'{ind * 4}<Time Value="{text}" />',
                f'{ind * 4}<Attribute Name="{name}" AttributeType="{"Vector" if vector else "Scalar"}" Center="{centre}">',
                f'{ind * 5}<DataItem Dimensions="{rows} {3 if vector else 1}" Format="HDF">'
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
