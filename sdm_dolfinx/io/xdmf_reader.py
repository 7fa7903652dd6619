"""A run's ``solution.xdmf`` read back as numpy arrays, and rewritten for ParaView.

* :func:`read_xdmf` loads mesh, times and fields with h5py (no ParaView, no dolfinx) into a
  :class:`Series`; :func:`von_mises` is the plane-strain stress of its displacement.
* :func:`merge_xdmf` rewrites dolfinx's XDMF, which stores every field as its own temporal
  grid (ParaView then shows four overlapping copies of the mesh, each carrying one array,
  and "Warp By Scalar" + "colour by contact_stress" fails), into one temporal grid whose
  every time step carries all fields. Same HDF5 file, only the XML differs.

This module imports only the standard library at load time (numpy and h5py inside the
functions) and nothing of the package, so a ParaView ``pvpython`` script and the pyvista
child process of :mod:`.render` can load it by path. Call it on one rank (Debian's h5py is serial).
"""
import json
import os
import xml.etree.ElementTree as ET
from pathlib import Path

#: the four linear triangles of a quadratic (VTK-ordered) triangle, for drawing and gradients
_SUB_TRIANGLES = ((0, 3, 5), (3, 1, 4), (5, 4, 2), (3, 4, 5))


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
        cell_type: the Xdmf topology name (``"Triangle"``, ``"Triangle_6"``, ...).
        times: sorted list of output times.
        run: the run's ``run.json`` (empty dict when there is none).
    """

    def __init__(self, points, cells, cell_type, times, datasets, h5path, run, xdmf=None):
        self.points, self.cells, self.cell_type, self.times = points, cells, cell_type, times
        self.xdmf = xdmf
        self._datasets, self._h5path, self.run = datasets, h5path, run

    @property
    def fields(self):
        """Names of the fields stored at the output times."""
        return sorted(self._datasets)

    def field(self, name, time):
        """The nodal values of ``name`` at the output time nearest to ``time``, shape (n,) or (n, k)."""
        import h5py
        import numpy as np
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

    def vertex_mask(self):
        """True at the nodes that are cell vertices (not the midside nodes of quadratic cells)."""
        import numpy as np
        corners = {"PolyLine": 2, "Edge_3": 2, "Tetrahedron": 4, "Tetrahedron_10": 4}.get(self.cell_type, 3)
        mask = np.zeros(len(self.points), dtype=bool)
        mask[self.cells[:, :corners].ravel()] = True
        return mask

    def linear_triangles(self):
        """(m', 3) straight triangles covering the mesh (quadratic ones split in four)."""
        import numpy as np
        if self.cell_type == "Triangle":
            return self.cells
        if self.cell_type == "Triangle_6":
            return np.concatenate([self.cells[:, list(s)] for s in _SUB_TRIANGLES])
        raise ValueError(f"cannot draw {self.cell_type} cells")

    def lame(self):
        """(lambda, mu) from run.json's parameters (0 and 1 when absent)."""
        p = self.parameters
        return float(p.get("lame_lambda", 0.0)), float(p.get("lame_mu", 1.0))

    def von_mises(self, displacement):
        """:func:`von_mises` of ``displacement`` with this run's Lamé parameters."""
        return von_mises(self, displacement, *self.lame())

    def stress_range(self, times):
        """[0, the largest von Mises stress over ``times``] (a common colour scale; [0, 1] when 0)."""
        import numpy as np
        top = max(float(np.max(self.von_mises(self.field("displacement", t)))) for t in times)
        return [0.0, top if top > 0 else 1.0]


def read_xdmf(path):
    """Read a dolfinx ``solution.xdmf`` (or its merged version) into a :class:`Series`.

    Args:
        path: the XDMF file or the run's folder.
    """
    import h5py
    import numpy as np
    path = Path(path)
    if path.is_dir():
        path = path / "solution.xdmf"
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
    return Series(points, cells, top.get("TopologyType"), times, datasets, h5path, run, path.resolve())


def von_mises(series, displacement, lame_lambda, lame_mu):
    """Plane-strain von Mises stress of a vertex displacement, one value per linear triangle.

    The displacement is piecewise linear on :meth:`Series.linear_triangles`, so the strain is
    constant on each of them; sigma_zz = lambda tr(eps) (plane strain).
    """
    import numpy as np
    tri = series.linear_triangles()
    x = series.points[:, :2][tri]                 # (m, 3, 2)
    u = displacement[:, :2][tri]
    d = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=1)       # rows: edge vectors
    du = np.stack([u[:, 1] - u[:, 0], u[:, 2] - u[:, 0]], axis=1)
    grad = np.linalg.solve(d, du).transpose(0, 2, 1)                     # grad[i, j] = du_i/dx_j
    eps = 0.5 * (grad + grad.transpose(0, 2, 1))
    tr = eps[:, 0, 0] + eps[:, 1, 1]
    sxx = lame_lambda * tr + 2 * lame_mu * eps[:, 0, 0]
    syy = lame_lambda * tr + 2 * lame_mu * eps[:, 1, 1]
    sxy = 2 * lame_mu * eps[:, 0, 1]
    szz = lame_lambda * tr
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3 * sxy ** 2)
