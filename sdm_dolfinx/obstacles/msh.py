"""gmsh's ASCII .msh files (formats 2.2 and 4.1): nodes and elements, by gmsh element type.

Read here rather than through the ``gmsh`` module: gmsh 4.8 (Debian 12) cannot tell whether a caller's
session is open (no ``gmsh.isInitialized``), so a reader that initialised and finalised it would close
that session; a plain parser also reads on every rank without gmsh's global state. Binary files are
refused (gmsh writes ASCII unless ``Mesh.Binary = 1``).
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from sdm_dolfinx.obstacles.base import Array, ObstacleError

LINE, TRIANGLE = 1, 2                          # gmsh's 2-node line and 3-node triangle
Mesh = tuple[dict[int, list[float]], dict[int, list[list[int]]]]


def _sections(text: str) -> dict[str, Iterator[list[str]]]:
    """The non-empty body lines, split, of each ``$Name ... $EndName`` section (the first of a name)."""
    out: dict[str, Iterator[list[str]]] = {}
    for m in re.finditer(r"^\$(\w+)[ \t]*\n(.*?)^\$End\1\b", text, re.M | re.S):
        out.setdefault(m.group(1), iter([r.split() for r in m.group(2).splitlines() if r.strip()]))
    return out


def _read_v2(s: dict[str, Iterator[list[str]]]) -> Mesh:
    count = int(next(s["Nodes"])[0])
    nodes = {int(r[0]): [float(v) for v in r[1:4]] for r in (next(s["Nodes"]) for _ in range(count))}
    cells: dict[int, list[list[int]]] = {}
    for _ in range(int(next(s["Elements"])[0])):
        r = [int(v) for v in next(s["Elements"])]          # tag, type, number of tags, tags..., nodes...
        cells.setdefault(r[1], []).append(r[3 + r[2]:])
    return nodes, cells


def _read_v4(s: dict[str, Iterator[list[str]]]) -> Mesh:
    nodes: dict[int, list[float]] = {}
    cells: dict[int, list[list[int]]] = {}
    for _ in range(int(next(s["Nodes"])[0])):              # blocks: entity dim, tag, parametric, count
        count = int(next(s["Nodes"])[3])
        tags = [int(next(s["Nodes"])[0]) for _ in range(count)]
        nodes.update({tag: [float(v) for v in next(s["Nodes"])[:3]] for tag in tags})
    for _ in range(int(next(s["Elements"])[0])):           # blocks: entity dim, tag, element type, count
        _, _, etype, count = (int(v) for v in next(s["Elements"])[:4])
        cells.setdefault(etype, []).extend([int(v) for v in next(s["Elements"])[1:]] for _ in range(count))
    return nodes, cells


def read(path: Any) -> tuple[Array, dict[int, Array]]:
    """(points (N, 3), {gmsh element type: node indices (m, k) into points}) of an ASCII .msh file."""
    p = Path(path)
    if not p.is_file():
        raise ObstacleError(f"surface mesh file {str(p)!r} does not exist")
    try:
        s = _sections(p.read_text())
    except UnicodeDecodeError:
        s = {"MeshFormat": iter([["?", "1"]])}
    head = next(s["MeshFormat"], []) if "MeshFormat" in s else None
    if head is None:
        raise ObstacleError(f"{p}: not a gmsh .msh file (no complete $MeshFormat section)")
    if len(head) < 2 or head[1] != "0":
        raise ObstacleError(f"{p}: not an ASCII .msh file (binary? save it with Mesh.Binary = 0)")
    if "Nodes" not in s or "Elements" not in s:
        raise ObstacleError(f"{p}: no complete $Nodes or $Elements section (no mesh in this .msh file)")
    if head[0][:2] not in ("2.", "4."):
        raise ObstacleError(f"{p}: .msh format {head[0]} is not read (2.2 and 4.1 are)")
    try:
        nodes, cells = (_read_v2 if head[0].startswith("2.") else _read_v4)(s)
        tags = np.array(sorted(nodes), dtype=np.int64)
        points = np.array([nodes[t] for t in tags], dtype=float).reshape(-1, 3)
        conn = {etype: np.array(c, dtype=np.int64) for etype, c in cells.items()}
    except (StopIteration, ValueError, IndexError):
        raise ObstacleError(f"{p}: malformed .msh file (format {head[0]})") from None
    if not np.all(np.isfinite(points)):
        raise ObstacleError(f"{p}: non-finite node coordinates")
    out = {}
    for etype, a in conn.items():
        idx = np.searchsorted(tags, a)
        if a.ndim != 2 or np.any(idx >= len(tags)) or np.any(tags[np.minimum(idx, len(tags) - 1)] != a):
            raise ObstacleError(f"{p}: elements of gmsh type {etype} refer to nodes that are not in $Nodes")
        out[etype] = idx
    return points, out
