"""A run's ``solution.xdmf`` read back as numpy arrays, and rewritten for ParaView.

* :func:`read_xdmf` loads mesh, times and fields with h5py (no ParaView, no dolfinx) into a
  :class:`Series`; :func:`von_mises` is the plane-strain stress of its displacement.
* :func:`merge_xdmf` rewrites dolfinx's XDMF, which stores every field as its own temporal
  grid (ParaView then shows four overlapping copies of the mesh, each carrying one array,
  and "Warp By Scalar" + "colour by contact_stress" fails), into one temporal grid whose
  every time step carries all fields. Same HDF5 file, only the XML differs.

* :meth:`Series.surface_triangles` and :meth:`Series.linear_cells` split the cells drawn
  (triangles, or the boundary faces of tetrahedra) and the cells whose strain is computed
  into straight triangles and tetrahedra (quadratic ones into 4 and 8).

This module imports only the standard library at load time (numpy and h5py inside the
functions) and nothing of the package but :mod:`sdm_dolfinx.errors` (by path when it is loaded
by path), so a ParaView ``pvpython`` script and the pyvista child process of :mod:`sdm_dolfinx.post.render`
can load it by path. Call it on one rank (Debian's h5py is serial).
"""
import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING


def _errors_by_path():
    """sdm_dolfinx/errors.py loaded by path (it imports nothing)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("sdm_render_errors", Path(__file__).resolve().parents[1] / "errors.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


if TYPE_CHECKING or __package__:      # imported as sdm_dolfinx.io.xdmf_reader
    from sdm_dolfinx.errors import SdmError
else:                                 # loaded by path: errors.py by path too
    SdmError = _errors_by_path().SdmError


class RenderError(SdmError, ValueError):
    """A run (or a request) that cannot be drawn: said in one line, nothing written."""


#: the four linear triangles of a quadratic (VTK-ordered) triangle, for drawing and gradients
_SUB_TRIANGLES = ((0, 3, 5), (3, 1, 4), (5, 4, 2), (3, 4, 5))
#: the eight linear tetrahedra of a quadratic (VTK-ordered) tetrahedron: its four corners and the
#: inner octahedron cut along the diagonal 4-9 (the midpoints of the edges 0-1 and 2-3)
_SUB_TETRAHEDRA = ((0, 4, 6, 7), (4, 1, 5, 8), (6, 5, 2, 9), (7, 8, 9, 3),
                   (4, 5, 6, 9), (4, 6, 7, 9), (4, 7, 8, 9), (4, 8, 5, 9))
#: a tetrahedron's faces (the face opposite each vertex) and, in VTK's quadratic tetrahedron,
#: the mid-edge node of each edge
_TET_FACES = ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))
_TET_EDGE_NODE = {(0, 1): 4, (1, 2): 5, (0, 2): 6, (0, 3): 7, (1, 3): 8, (2, 3): 9}
#: the Xdmf topologies drawn here -> (topological dimension, corners per cell)
CELL_TYPES = {"PolyLine": (1, 2), "Edge_3": (1, 2), "Triangle": (2, 3), "Triangle_6": (2, 3),
              "Tetrahedron": (3, 4), "Tetrahedron_10": (3, 4)}


def merged_path(xdmf):
    """Where :func:`merge_xdmf` writes by default: ``solution.xdmf`` -> ``solution_paraview.xdmf``."""
    xdmf = Path(xdmf)
    return xdmf.with_name(xdmf.stem + "_paraview.xdmf")


def merge_xdmf(src, dst=None):
    """Write an XDMF file with one temporal grid holding every field at every time.

    dolfinx writes the mesh grid and then one temporal collection per function; ParaView's
    readers turn that into one block per function, each a full copy of the mesh with a single
    array. The file written here references the same HDF5 datasets (so it must stay next to
    ``src``) but lists, per time step, the mesh and all attributes of that time, and declares
    the float data as 8-byte (dolfinx 0.5 leaves Xdmf's 4-byte default, so ParaView reads
    ``solution.xdmf`` in single precision).

    Args:
        src: a ``solution.xdmf`` written by dolfinx.
        dst: the output path (default :func:`merged_path` of ``src``).

    Returns:
        The path written.
    """
    src = Path(src)
    dst = merged_path(src) if dst is None else Path(dst)
    root = ET.parse(src).getroot()
    domain = root.find("Domain")
    mesh = next(g for g in domain.findall("Grid") if g.get("GridType") == "Uniform")
    topology, geometry = mesh.find("Topology"), mesh.find("Geometry")
    times, attributes = [], {}
    for coll in domain.findall("Grid"):
        if coll.get("GridType") != "Collection":
            continue
        for g in coll.findall("Grid"):
            t = g.find("Time").get("Value")
            if t not in attributes:
                times.append(t)
                attributes[t] = []
            attributes[t].extend(g.findall("Attribute"))
    # dolfinx 0.5 omits the precision of its float data, and Xdmf's default is 4 bytes: ParaView
    # then reads the (8-byte) coordinates and fields in single precision. Say 8 (dolfinx writes
    # PETSc's double scalars).
    for item in list(geometry.iter("DataItem")) + [d for t in times for a in attributes[t] for d in a.iter("DataItem")]:
        if "Precision" not in item.attrib and item.get("NumberType", "Float") == "Float":
            item.set("NumberType", "Float")
            item.set("Precision", "8")
    out = ET.Element("Xdmf", {"Version": "3.0"})
    dom = ET.SubElement(out, "Domain")
    series = ET.SubElement(dom, "Grid", {"Name": "solution", "GridType": "Collection",
                                         "CollectionType": "Temporal"})
    for t in sorted(times, key=float):
        g = ET.SubElement(series, "Grid", {"Name": "solution", "GridType": "Uniform"})
        g.append(topology)
        g.append(geometry)
        ET.SubElement(g, "Time", {"Value": t})
        for a in attributes[t]:
            g.append(a)
    ET.indent(out)
    # (mpiutil.atomic_write is not used: importing the package would load dolfinx, see the docstring)
    tmp = dst.with_name(dst.name + ".tmp")
    with open(tmp, "wb") as fh:
        fh.write(b'<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n')
        ET.ElementTree(out).write(fh, encoding="utf-8")
        fh.write(b"\n")
    os.replace(tmp, dst)
    return dst


class Series:
    """A run's fields as numpy arrays, read from its XDMF/HDF5 files.

    Attributes:
        points: (n, 3) node coordinates.
        cells: (m, k) node indices per cell, VTK ordering.
        cell_type: the Xdmf topology name (``"Triangle"``, ``"Tetrahedron_10"``, ...).
        gdim: the mesh's geometric dimension (2 or 3 coordinates stored per node; 1-D meshes too).
        times: sorted list of output times.
        run: the run's ``run.json`` (empty dict when there is none).
    """

    def __init__(self, points, cells, cell_type, times, datasets, h5path, run, xdmf=None, gdim=None):
        self.points, self.cells, self.cell_type, self.times = points, cells, cell_type, times
        self.xdmf, self.gdim = xdmf, points.shape[1] if gdim is None else gdim
        self._datasets, self._h5path, self.run = datasets, h5path, run

    @property
    def fields(self):
        """Names of the fields stored at the output times."""
        return sorted(self._datasets)

    @property
    def tdim(self):
        """The cells' topological dimension (1, 2 or 3)."""
        return self._cell_info()[0]

    def _cell_info(self):
        if self.cell_type not in CELL_TYPES:
            raise RenderError(f"{self.xdmf}: cannot draw {self.cell_type} cells (only triangles and tetrahedra, "
                              f"linear or quadratic): open it in ParaView")
        return CELL_TYPES[self.cell_type]

    def field(self, name, time):
        """The nodal values of ``name`` at the output time nearest to ``time``, shape (n,) or (n, k)."""
        import h5py
        import numpy as np
        if name not in self._datasets:
            raise RenderError(f"{self.xdmf} has no field {name!r} (its fields: {', '.join(self.fields) or 'none'})")
        k = self.index(time)
        with h5py.File(self._h5path, "r") as h5:
            a = np.array(h5[self._datasets[name][k]])
        return a[:, 0] if a.ndim == 2 and a.shape[1] == 1 else a

    def index(self, time):
        """Index of the output time nearest to ``time``."""
        import numpy as np
        return int(np.argmin(np.abs(np.asarray(self.times) - time)))

    @property
    def parameters(self):
        """The problem's parameters from run.json."""
        return self.run.get("problem", {}).get("parameters", {})

    @property
    def problem_name(self):
        """The problem's name from run.json (``membrane``, ``disc``, ...)."""
        return self.run.get("problem", {}).get("name", "")

    def node_bodies(self, time):
        """(each node's body number, 0 for none; the bodies' names) of a run whose Problem declares
        ``bodies`` (the cell field ``body`` at ``time`` and run.json's ``problem.bodies``), else None.
        Bodies share no node (a run refuses them otherwise), so a node's body is that of any of its cells
        in a body (a cell of none may touch it)."""
        import numpy as np
        names = self.run.get("problem", {}).get("bodies")
        if not names or "body" not in self.fields:
            return None
        tag = np.zeros(len(self.points), dtype=np.int64)
        body = np.rint(self.field("body", time)).astype(np.int64).reshape(-1)
        np.maximum.at(tag, self.cells.reshape(-1), np.repeat(body, self.cells.shape[1]))
        return tag, list(names)

    def vertex_mask(self):
        """True at the nodes that are cell vertices (not the midside nodes of quadratic cells)."""
        import numpy as np
        mask = np.zeros(len(self.points), dtype=bool)
        mask[self.cells[:, :self._cell_info()[1]].ravel()] = True
        return mask

    def linear_triangles(self):
        """(m', 3) straight triangles covering a 2-D mesh (quadratic ones split in four)."""
        import numpy as np
        if self.cell_type == "Triangle":
            return self.cells
        if self.cell_type == "Triangle_6":
            return np.concatenate([self.cells[:, list(s)] for s in _SUB_TRIANGLES])
        raise RenderError(f"{self.xdmf}: {self.cell_type} cells are not triangles (see surface_triangles)")

    def linear_cells(self):
        """(m', 3) straight triangles or (m', 4) straight tetrahedra covering the mesh (quadratic
        cells split in four or eight): the displacement is taken linear on each (for strains)."""
        import numpy as np
        if self.tdim == 2:
            return self.linear_triangles()
        if self.cell_type == "Tetrahedron":
            return self.cells
        if self.cell_type == "Tetrahedron_10":
            return np.concatenate([self.cells[:, list(s)] for s in _SUB_TETRAHEDRA])
        raise RenderError(f"{self.xdmf}: no strain on {self.cell_type} cells")

    def boundary_faces(self):
        """(f, 3) or (f, 6) the faces of a tetrahedral mesh that belong to one cell only (its
        surface), as triangles (quadratic: corners, then the mid-edge nodes of 01, 12, 20)."""
        import numpy as np
        faces = np.concatenate([self.cells[:, list(f)] for f in _TET_FACES])
        key = np.sort(faces, axis=1)
        _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
        outer = np.sort(first[count == 1])
        if self.cell_type == "Tetrahedron":
            return faces[outer]
        cell, face = outer % len(self.cells), outer // len(self.cells)
        local = np.array(_TET_FACES)[face]                                     # (f, 3) local corners
        mids = [np.array([_TET_EDGE_NODE[tuple(sorted((a, b)))] for a, b in zip(local[:, i], local[:, (i + 1) % 3])])
                for i in range(3)]
        return np.column_stack([self.cells[cell, local[:, i]] for i in range(3)]
                               + [self.cells[cell, m] for m in mids])

    def surface_triangles(self):
        """(m', 3) straight triangles that draw the mesh: the triangles of a 2-D mesh, or the
        boundary surface of a 3-D one (quadratic faces split in four)."""
        import numpy as np
        if self.tdim == 2:
            return self.linear_triangles()
        if self.tdim != 3:
            raise RenderError(f"{self.xdmf}: a 1-D mesh has no surface to draw")
        faces = self.boundary_faces()
        if faces.shape[1] == 3:
            return faces
        return np.concatenate([faces[:, list(s)] for s in _SUB_TRIANGLES])

    @property
    def material(self):
        """The run's material (run.json's run option ``material``; ``linear`` for runs before it)."""
        return (self.run.get("run_options") or {}).get("material") or "linear"

    def lame(self):
        """(lambda, mu) from run.json's parameters ``lame_lambda`` and ``lame_mu``, or None when the
        problem does not declare both or the run's material is a problem file's own psi (its stress is
        then not known here)."""
        if self.material not in cauchy_table():
            return None
        p = self.parameters
        try:
            lame = float(p["lame_lambda"]), float(p["lame_mu"])
        except (KeyError, TypeError, ValueError):
            return None
        return lame

    def von_mises(self, displacement):
        """:func:`von_mises` of ``displacement`` with this run's Lamé parameters (see :meth:`lame`)."""
        lame = self.lame()
        if lame is None:
            raise RenderError(f"{self.xdmf}: run.json's problem parameters have no lame_lambda and lame_mu")
        return von_mises(self, displacement, *lame, material=self.material)

    def nodal_von_mises(self, displacement):
        """The von Mises stress averaged to the nodes from the cells around each (for smooth pictures)."""
        import numpy as np
        cells = self.linear_cells()
        vm = self.von_mises(displacement)
        total, count = np.zeros(len(self.points)), np.zeros(len(self.points))
        np.add.at(total, cells.ravel(), np.repeat(vm, cells.shape[1]))
        np.add.at(count, cells.ravel(), 1.0)
        return total / np.maximum(count, 1.0)

    def stress_range(self, times):
        """[0, the largest von Mises stress over ``times``] (a common colour scale; [0, 1] when 0)."""
        import numpy as np
        top = max(float(np.max(self.von_mises(self.field("displacement", t)))) for t in times)
        return [0.0, top if top > 0 else 1.0]


def read_xdmf(path):
    """Read a dolfinx ``solution.xdmf`` (or its merged version) into a :class:`Series`.

    Args:
        path: the XDMF file or the run's folder.

    Raises:
        RenderError: a file that is not such an XDMF, or whose HDF5 data cannot be read.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "solution.xdmf"
    try:
        return _read_xdmf(path)
    except (OSError, ET.ParseError, AttributeError, KeyError, IndexError, ValueError) as e:
        raise RenderError(f"cannot read {path}: {getattr(e, 'strerror', None) or e}") from None


def _read_xdmf(path):
    import h5py
    import numpy as np
    root = ET.parse(path).getroot()
    top = root.find(".//Topology")
    geo = root.find(".//Geometry")
    h5name = top.find("DataItem").text.strip().split(":")[0]
    h5path = path.parent / h5name
    datasets, times = {}, set()
    for g in root.iter("Grid"):
        t = g.find("Time")
        if t is None:
            continue
        times.add(float(t.get("Value")))
        for a in g.findall("Attribute"):
            dataset = a.find("DataItem").text.strip().split(":")[1]
            datasets.setdefault(a.get("Name"), {})[float(t.get("Value"))] = dataset
    times = sorted(times)
    datasets = {k: [v[t] for t in times] for k, v in datasets.items()}
    with h5py.File(h5path, "r") as h5:
        x = np.array(h5[geo.find("DataItem").text.strip().split(":")[1]])
        cells = np.array(h5[top.find("DataItem").text.strip().split(":")[1]], dtype=np.int64)
    points = np.zeros((x.shape[0], 3))
    points[:, :x.shape[1]] = x
    run_json = path.parent / "run.json"
    run = json.loads(run_json.read_text()) if run_json.exists() else {}
    return Series(points, cells, top.get("TopologyType"), times, datasets, h5path, run, path.resolve(),
                  gdim=x.shape[1])


def cauchy_table():
    """:data:`sdm_dolfinx.materials.cauchy.CAUCHY`, its file loaded by path: this module runs in pvpython and in
    the pictures' child process without the package, whose import starts MPI (a child of an MPI run then
    hangs: the test suite's render children did, until memory ran out)."""
    global _CAUCHY
    if _CAUCHY is None:
        import importlib.util
        path = Path(__file__).resolve().parent.parent / "materials" / "cauchy.py"
        spec = importlib.util.spec_from_file_location("sdm_render_cauchy", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _CAUCHY = module.CAUCHY
    return _CAUCHY


_CAUCHY = None


def von_mises(series, displacement, lame_lambda, lame_mu, material="linear"):
    """The von Mises stress of a nodal displacement, one value per cell of
    :meth:`Series.linear_cells` (on which the displacement is linear, so the strain constant): of
    Hooke's sigma(eps) for the linear material, of the Cauchy stress F S F^T / J of a hyperelastic one
    (:data:`sdm_dolfinx.materials.cauchy.CAUCHY`: its second Piola-Kirchhoff stress S(C)).

    2-D: plane strain (F_zz = 1), with the out-of-plane stress; 3-D: the full stress.
    """
    import numpy as np
    CAUCHY = cauchy_table()
    cells = series.linear_cells()
    d = cells.shape[1] - 1                         # 2 (triangles) or 3 (tetrahedra)
    x = series.points[:, :d][cells]                # (m, d + 1, d)
    u = displacement[:, :d][cells]
    edges = x[:, 1:] - x[:, :1]                    # rows: edge vectors
    du = u[:, 1:] - u[:, :1]
    grad = np.linalg.solve(edges, du).transpose(0, 2, 1)                 # grad[i, j] = du_i/dx_j
    full = np.zeros((len(cells), 3, 3))
    full[:, :d, :d] = grad
    sigma = CAUCHY[material](full, lame_lambda, lame_mu)       # (m, 3, 3)
    dev = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] / 3.0 * np.eye(3)
    return np.sqrt(1.5 * np.sum(dev * dev, axis=(1, 2)))
