"""``obstacles.xdmf``: the problem's rigid obstacles at every written step, as their own mesh
(docs/outputs.md), written beside ``solution.xdmf`` and read back by :func:`read_obstacles`.

One XDMF file, its data inline (XML, 17 significant digits: read back exactly; no HDF5 file), a
temporal collection with one Grid per written step (``Name="step_<n>"``, ``Time`` t_n; fixed obstacles: the
first grid's mesh included in the others with ``xi:include``, as dolfinx's own XDMF does): 2-D the
segments of the obstacles' outlines (``Polyline``, 2 nodes per element), 3-D their triangulated
surfaces (``Triangle``), each clipped to one box fixed for the run (the body's reference bounding box
grown to ``BOX_FACTOR`` times its largest side on each side of its middle:
:func:`sdm_dolfinx.obstacles.surface.enlarged_box`), with a cell attribute ``obstacle`` (the index of
the obstacle in the problem's list). ParaView opens it with its XDMF reader (``Xdmf3ReaderS``) beside
``solution.xdmf``. A step whose obstacles are all outside the box has a Grid without cells (no Geometry,
no Topology): ParaView shows nothing then. An
obstacle of a shape :mod:`sdm_dolfinx.obstacles.surface` does not draw is named in the grid's
``<Information Name="not_written">``.

Only rank 0 writes (the obstacles are the same on every rank); every grid is appended in place (the
closing tags written again after it), so a write costs its own grid's size. A restarted run writes the
file again from the steps it keeps (the obstacles are functions of t alone).
"""
import os
import xml.etree.ElementTree as ET
from xml.sax.saxutils import escape
from pathlib import Path

#: the box of the pictures: half sides this many times the body's largest side
BOX_FACTOR = 1.5
NAME = "obstacles.xdmf"
_HEAD = ('<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
         '<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">\n  <Domain>\n'
         '    <Grid Name="obstacles" GridType="Collection" CollectionType="Temporal">\n')
_TAIL = "    </Grid>\n  </Domain>\n</Xdmf>\n"


def _numbers(a, fmt):
    return "\n".join(" ".join(fmt % v for v in row) for row in a.reshape(len(a), -1))


#: a fixed obstacle's later grids: the first grid's mesh and attribute (as dolfinx's solution.xdmf does)
_SAME = ('        <xi:include xpointer="xpointer(/Xdmf/Domain/Grid/Grid[1]/*[self::Topology or self::Geometry or '
         'self::Attribute])" />\n')


def grid_xml(n, t, m, same=False):
    """The Grid of step ``n`` at the time ``t`` for the mesh ``m`` (:func:`sdm_dolfinx.obstacles.surface.mesh`);
    ``same``: the first grid's mesh, included (a fixed obstacle)."""
    points, cells, which = m["points"], m["cells"], m["which"]
    out = [f'      <Grid Name="step_{n}" GridType="Uniform">\n        <Time Value="{float(t)!r}" />\n']
    if m["missing"]:
        said = escape(", ".join(m["missing"]), {'"': "&quot;"})
        out.append(f'        <Information Name="not_written" Value="{said}" />\n')
    if len(cells) and same:
        out.append(_SAME)
    elif len(cells):
        kind = "Polyline\" NodesPerElement=\"2" if cells.shape[1] == 2 else "Triangle"
        out.append(f'        <Topology TopologyType="{kind}" NumberOfElements="{len(cells)}">\n'
                   f'          <DataItem Dimensions="{len(cells)} {cells.shape[1]}" NumberType="Int" '
                   f'Format="XML">\n{_numbers(cells, "%d")}\n          </DataItem>\n        </Topology>\n'
                   f'        <Geometry GeometryType="XYZ">\n          <DataItem Dimensions="{len(points)} 3" '
                   f'Precision="8" NumberType="Float" Format="XML">\n{_numbers(points, "%.17g")}\n'
                   f'          </DataItem>\n        </Geometry>\n'
                   f'        <Attribute Name="obstacle" AttributeType="Scalar" Center="Cell">\n'
                   f'          <DataItem Dimensions="{len(which)}" NumberType="Int" Format="XML">\n'
                   f'{" ".join(str(int(w)) for w in which)}\n          </DataItem>\n        </Attribute>\n')
    out.append("      </Grid>\n")
    return "".join(out)


class ObstacleWriter:
    """``obstacles.xdmf`` of a run (rank 0 only; see the module).

    Args:
        path: the file.
        obstacles: the Problem's obstacles.
        box: (lo, hi), the box their surfaces are clipped to (a 2-D run's has no z extent).
        kept: a restart's written steps and times [(n, t_n), ...] (written again first), or None.
    """

    def __init__(self, path, obstacles, box, kept=None):
        self.path, self.obstacles, self.box = Path(path), list(obstacles), box
        self.moving = any(getattr(ob, "moves", False) for ob in self.obstacles)
        self._fixed = None
        self.steps = []
        body = []
        for n, t in kept or []:
            body.append(self._grid(n, t))
            self.steps.append(n)
        with open(self.path, "w") as fh:
            fh.write(_HEAD + "".join(body) + _TAIL)

    def _grid(self, n, t):
        from sdm_dolfinx.obstacles.surface import mesh
        if self.moving:
            return grid_xml(n, t, mesh(self.obstacles, t, self.box))
        if self._fixed is None:
            self._fixed = mesh(self.obstacles, 0.0, self.box)
        return grid_xml(n, t, self._fixed, same=bool(self.steps))

    def write(self, n, t):
        """Append the grid of step ``n`` at the time ``t``."""
        text = self._grid(n, t)
        with open(self.path, "r+b") as fh:
            end = fh.seek(-len(_TAIL), os.SEEK_END)
            try:
                fh.write((text + _TAIL).encode())
                fh.truncate()
                fh.flush()
            except OSError:                          # (a full disc) the file as it was: no more space needed
                fh.seek(end)
                fh.write(_TAIL.encode())
                fh.truncate()
                raise
        self.steps.append(n)

    def drop(self, n):
        """Take step ``n``'s grid back out (the step's other writes failed)."""
        if not self.steps or self.steps[-1] != n:
            return
        text = self.path.read_text()
        start = text.rindex(f'      <Grid Name="step_{n}"')
        with open(self.path, "w") as fh:
            fh.write(text[:start] + _TAIL)
        self.steps.pop()


def read_obstacles(path):
    """The grids of an ``obstacles.xdmf`` (or of the run folder's): a list, in time order, of dicts
    ``step``, ``t``, ``points`` (n, 3), ``cells`` (m, 2 or 3), ``which`` (m,), ``not_written`` (the
    obstacles of a shape that is not written, as "kind (obstacle i)", or "")."""
    import numpy as np
    path = Path(path)
    if path.is_dir():
        path = path / NAME
    out, first = [], None
    for g in ET.parse(path).getroot().iter("Grid"):
        if g.get("GridType") != "Uniform":
            continue
        first = g if first is None else first
        same = g.find("{http://www.w3.org/2001/XInclude}include") is not None      # the first grid's mesh
        top, geo, att = (first if same else g).find("Topology"), (first if same else g).find("Geometry"), \
            (first if same else g).find("Attribute")

        def array(item, dtype, shape):
            return np.array(item.find("DataItem").text.split(), dtype=dtype).reshape(shape)
        k = 2 if top is not None and top.get("TopologyType") == "Polyline" else 3
        out.append({"step": int(g.get("Name").split("_")[1]), "t": float(g.find("Time").get("Value")),
                    "points": array(geo, float, (-1, 3)) if geo is not None else np.zeros((0, 3)),
                    "cells": array(top, np.int64, (-1, k)) if top is not None else np.zeros((0, 3), np.int64),
                    "which": array(att, np.int32, (-1,)) if att is not None else np.zeros(0, np.int32),
                    "not_written": next((i.get("Value") for i in g.findall("Information")
                                         if i.get("Name") == "not_written"), "")})
    return sorted(out, key=lambda d: d["t"])
