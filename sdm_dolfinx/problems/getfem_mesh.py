"""GetFEM's text mesh format (``.mesh``): the curved P2 disc meshes of the paper's program.

GetFEM's ``tests/meshes/disc_P2_h*.mesh`` (the meshes of the paper's Table 2) hold a
``BEGIN POINTS LIST`` block (``POINT i x y``) and a ``BEGIN MESH STRUCTURE DESCRIPTION``
block (``CONVEX i 'GT_PK(2,2)' n0 ... n5``); ``%`` starts a comment, ``POINT COUNT`` and
``CONVEX COUNT`` lines are ignored, as is everything after the structure block (regions).
GetFEM's quadratic triangle lists its nodes row by row on the reference triangle
(v0, m01, v1, m02, m12, v2); we convert them to gmsh's 6-node order, make every cell
counter-clockwise, check that no curved cell is folded, and hand the cells to dolfinx's
``create_mesh`` (which partitions them, as ``model_to_mesh`` does for gmsh files).

The disc of these files has its lowest point at the origin (centre (0, R)): the caller
translates the points to its own placement (see ``disc_mesh.read_mesh``).
"""
import re
from pathlib import Path

from mpi4py import MPI

import numpy as np
import ufl

from sdm_dolfinx import compat
from sdm_dolfinx.errors import SdmError

#: the one convex type read: GetFEM's quadratic (curved) triangle
PK22 = "GT_PK(2,2)"
#: GetFEM's PK(2,2) node order (v0, m01, v1, m02, m12, v2) -> gmsh's 6-node triangle
#: (v0, v1, v2, m01, m12, m20)
GETFEM_TO_GMSH = np.array([0, 2, 5, 1, 4, 3])
#: gmsh's 6-node triangle -> dolfinx's (midpoints of the edges (1,2), (0,2), (0,1)): the
#: permutation dolfinx's gmsh reader applies (``dolfinx.cpp.io.perm_gmsh(triangle, 6)``)
GMSH_TO_DOLFINX = np.array([0, 1, 2, 4, 5, 3])
#: smallest accepted Jacobian determinant of a cell, relative to the mean of |det J| over
#: the mesh: below it a cell is folded or degenerate (a healthy curved cell stays far above)
MIN_DET_RATIO = 1e-8

_CONVEX = re.compile(r"^CONVEX\s+(\S+)\s+('[^']*'|[^'\s]\S*)\s*(.*)$", re.IGNORECASE)
_HEADERS = ("BEGIN POINTS LIST", "END POINTS LIST", "BEGIN MESH STRUCTURE DESCRIPTION",
            "END MESH STRUCTURE DESCRIPTION")


class GetfemFormatError(SdmError, ValueError):
    """Why a ``.mesh`` file cannot be used, in one line (file and line number)."""


def _lines(path):
    """(line number, text without comment) of the file's non-blank lines."""
    path = Path(path)
    if not path.is_file():
        raise GetfemFormatError(f"{path}: no such file")
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise GetfemFormatError(f"{path}: cannot read it as a GetFEM text mesh ({type(e).__name__})") from None
    for n, line in enumerate(text.splitlines(), start=1):
        line = line.split("%", 1)[0].strip()
        if line:
            yield n, line


def _point(path, n, line):
    """(id, (x, y)) of a ``POINT i x y [z]`` line (z must be 0: a plane mesh)."""
    tok = line.split()
    try:
        if len(tok) not in (4, 5) or tok[0].upper() != "POINT":
            raise ValueError
        i, xyz = int(tok[1]), [float(t) for t in tok[2:]]
    except ValueError:
        raise GetfemFormatError(f"{path}:{n}: cannot read {line!r} (expected 'POINT i x y')") from None
    if i < 0 or not np.all(np.isfinite(xyz)) or (len(xyz) == 3 and xyz[2] != 0.0):
        raise GetfemFormatError(f"{path}:{n}: {line!r}: a point of a plane mesh has an index >= 0 and finite "
                                "x y (z = 0 if given)")
    return i, xyz[:2]


def _convex(path, n, line):
    """(id, six point ids) of a ``CONVEX i 'GT_PK(2,2)' n0 ... n5`` line."""
    m = _CONVEX.match(line)
    if m is None:
        raise GetfemFormatError(f"{path}:{n}: cannot read {line!r} (expected \"CONVEX i 'GT_PK(2,2)' n0 ... n5\")")
    kind = m.group(2).strip("'").replace(" ", "")
    if kind.upper() != PK22:
        raise GetfemFormatError(f"{path}:{n}: convex {m.group(1)} is '{kind}': only GetFEM's quadratic triangles "
                                f"'{PK22}' are read (the curved P2 disc)")
    try:
        i, nodes = int(m.group(1)), [int(t) for t in m.group(3).split()]
        if len(nodes) != 6 or i < 0 or min(nodes) < 0:
            raise ValueError
    except ValueError:
        raise GetfemFormatError(f"{path}:{n}: cannot read {line!r} (expected a convex index and six point "
                                "indices >= 0)") from None
    return i, nodes


def _blocks(path):
    """The points and convexes of the file: ({id: (x, y)}, [(line, id, nodes)])."""
    points, convexes, seen = {}, [], set()
    state, last = 0, 0                # state: index in _HEADERS of the last header met
    for n, line in _lines(path):
        last = n
        head = " ".join(line.split()).upper()
        if state < len(_HEADERS) and head == _HEADERS[state]:
            state += 1
        elif state == len(_HEADERS):
            break                     # regions and other blocks after the mesh: not ours
        elif state == 1 and head.startswith("POINT COUNT") or state == 3 and head.startswith("CONVEX COUNT"):
            continue
        elif state == 1:
            i, xy = _point(path, n, line)
            if i in points:
                raise GetfemFormatError(f"{path}:{n}: point {i} is defined twice")
            points[i] = xy
        elif state == 3:
            i, nodes = _convex(path, n, line)
            if i in seen:
                raise GetfemFormatError(f"{path}:{n}: convex {i} is defined twice")
            seen.add(i)
            convexes.append((n, i, nodes))
        elif state in (0, 2):
            continue                  # text between blocks: skipped, as GetFEM's reader does
    if state < len(_HEADERS):
        raise GetfemFormatError(f"{path}: the file ends (line {last}) before '{_HEADERS[state]}': truncated or "
                                "not a GetFEM mesh")
    if not convexes:
        raise GetfemFormatError(f"{path}: no convex in its mesh structure description")
    return points, convexes


def parse(path):
    """The mesh of a GetFEM ``.mesh`` file of quadratic triangles, in the file's coordinates.

    Returns:
        (x, cells): the points (n, 2) in mm, and the cells (m, 6) as rows of ``x`` in gmsh's
        6-node order, every cell counter-clockwise (:func:`orient`).

    Raises:
        GetfemFormatError: a missing or malformed file, another convex type, an unknown point.
    """
    points, convexes = _blocks(path)
    ids = np.array(sorted(points), dtype=np.int64)
    x = np.array([points[i] for i in ids], dtype=np.float64).reshape(-1, 2)
    row = {int(i): r for r, i in enumerate(ids)}
    cells = np.empty((len(convexes), 6), dtype=np.int64)
    for k, (n, i, nodes) in enumerate(convexes):
        missing = [p for p in nodes if p not in row]
        if missing:
            raise GetfemFormatError(f"{path}:{n}: convex {i} uses point {missing[0]}, which the points list "
                                    "does not define")
        cells[k] = [row[p] for p in nodes]
    cells = cells[:, GETFEM_TO_GMSH]
    _check_edges(path, cells)
    return x, orient(path, x, cells)


def _check_edges(path, cells):
    """GetfemFormatError unless each edge has one midpoint node in every cell that shares it
    (else dolfinx would keep one of them and silently change the other cell's geometry)."""
    ends = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])
    mid = np.concatenate([cells[:, 3], cells[:, 4], cells[:, 5]])
    edges = np.column_stack([np.sort(ends, axis=1), mid])
    pairs = np.unique(edges[:, :2], axis=0)
    if len(np.unique(edges, axis=0)) != len(pairs):
        raise GetfemFormatError(f"{path}: two cells give an edge different midpoint nodes: the curved "
                                "mesh is not conforming")


def det_jacobian(x, cells):
    """det of the P2 map's Jacobian at each cell's six nodes and centroid, (m, 7), for
    ``cells`` in gmsh's order on the reference triangle (0,0), (1,0), (0,1)."""
    ref = np.array([[0, 0], [1, 0], [0, 1], [0.5, 0], [0.5, 0.5], [0, 0.5], [1 / 3, 1 / 3]])
    lam = np.column_stack([1 - ref.sum(axis=1), ref])                 # barycentric coordinates
    dlam = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
    grads = np.empty((len(ref), 6, 2))
    for v in range(3):                 # vertex v: L_v (2 L_v - 1); midpoint of (a, b): 4 L_a L_b
        grads[:, v] = (4 * lam[:, v] - 1)[:, None] * dlam[v]
    for k, (a, b) in enumerate(((0, 1), (1, 2), (2, 0))):
        grads[:, 3 + k] = 4 * (lam[:, b][:, None] * dlam[a] + lam[:, a][:, None] * dlam[b])
    J = np.einsum("cnd,pnr->cpdr", x[cells], grads)
    return J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]


def orient(path, x, cells):
    """``cells`` (gmsh order) with the clockwise ones reversed (v1 <-> v2, m01 <-> m20), so
    that det J > 0 everywhere; GetfemFormatError if a cell's det J changes sign or vanishes
    (a folded or degenerate curved triangle; :data:`MIN_DET_RATIO`)."""
    cells = cells.copy()
    flip = det_jacobian(x, cells)[:, -1] < 0
    cells[np.ix_(flip, [1, 2, 3, 5])] = cells[np.ix_(flip, [2, 1, 5, 3])]
    det = det_jacobian(x, cells)
    bad = np.flatnonzero(det.min(axis=1) <= MIN_DET_RATIO * np.abs(det).mean())
    if bad.size:
        raise GetfemFormatError(f"{path}: cell {bad[0]} (counting from 0) is folded or degenerate: its Jacobian "
                                f"determinant ranges over [{det[bad[0]].min():.3g}, {det[bad[0]].max():.3g}] mm^2")
    return cells


def read(path, shift, comm=MPI.COMM_WORLD, rank=0):
    """The dolfinx mesh of a GetFEM ``.mesh`` file, its points translated by ``shift`` (mm).

    ``rank`` reads the file; dolfinx partitions the cells over ``comm`` (every rank calls this).

    Raises:
        GetfemFormatError: on every rank, when :func:`parse` refuses the file.
    """
    err = None
    if comm.rank == rank:
        try:
            x, cells = parse(path)
            x, cells = x + np.asarray(shift, dtype=np.float64), cells[:, GMSH_TO_DOLFINX]
        except GetfemFormatError as e:
            err = str(e)
    else:
        x, cells = np.empty((0, 2)), np.empty((0, 6), dtype=np.int64)
    err = comm.bcast(err, root=rank)
    if err:
        raise GetfemFormatError(err)
    domain = ufl.Mesh(compat.element("Lagrange", "triangle", 2, (2,)))
    return compat.create_mesh(comm, cells, x, domain)
