"""The paper's own disc meshes (GetFEM's ``disc_P2_h*.mesh``, Table 2 rows 1-4) read by
``disc --mesh FILE.mesh``: their P2 dof counts are the paper's, their geometry is the curved
P2 disc placed as ours, a run on one agrees with the run on the same mesh converted to gmsh's
``.msh``, and broken files are refused in one line.

The files live outside the project (``/work/shared/data/getfem-disc-meshes``); without them
every test here skips (decided on rank 0 and broadcast, so that all ranks skip together).
"""
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat, simulate
from sdm_dolfinx.problems import disc, disc_mesh
from sdm_dolfinx.paper.design import PAPER_MESH_DIRS, paper_mesh_dir

COMM = MPI.COMM_WORLD
#: where sdm_dolfinx looks for them ($SDM_GETFEM_MESHES, then shared/ beside the checkout or a parent folder)
DATA = paper_mesh_dir() or PAPER_MESH_DIRS[1]
R, HEIGHT = 20.0, 10.0                     # the disc's defaults (mm): centre (0, 30), A at y = 10
CY = R + HEIGHT
#: the paper's Table 2, rows 1-4: P2 vector displacement dofs of GetFEM's meshes
TABLE_2 = {"disc_P2_h4.mesh": 622, "disc_P2_h2.mesh": 2782, "disc_P2_h1.mesh": 11306,
           "disc_P2_h0_5.mesh": 45706}
#: GetFEM's PK(2,2) node order (v0, m01, v1, m02, m12, v2) -> gmsh's (v0, v1, v2, m01, m12, m20)
TO_GMSH = [0, 2, 5, 1, 4, 3]


@pytest.fixture(autouse=True)
def _needs_data():
    if not COMM.bcast(DATA.is_dir() if COMM.rank == 0 else None, root=0):
        pytest.skip(f"GetFEM's disc meshes are not in {DATA}")


def _file(name):
    return DATA / name


def _getfem_arrays(path):
    """(points (n, 2), cells (m, 6) in gmsh's order) of a GetFEM file, read here by a few lines
    of our own (not the package's reader): a second route to the same mesh."""
    pts, cells = {}, []
    for line in Path(path).read_text().splitlines():
        tok = line.split()
        if tok[:1] == ["POINT"] and tok[1] != "COUNT":
            pts[int(tok[1])] = (float(tok[2]), float(tok[3]))
        elif tok[:1] == ["CONVEX"] and tok[1] != "COUNT":
            cells.append([int(t) for t in tok[3:9]])
    assert sorted(pts) == list(range(len(pts)))
    return np.array([pts[i] for i in range(len(pts))]), np.array(cells)[:, TO_GMSH]


def _boundary_arcs(cells):
    """(start, end, midpoint) node rows of the boundary edges (edges of one cell only), and
    the cell of each."""
    ends = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])
    mids = np.concatenate([cells[:, 3], cells[:, 4], cells[:, 5]])
    _, first, count = np.unique(np.sort(ends, axis=1), axis=0, return_index=True, return_counts=True)
    keep = first[count == 1]
    return ends[keep, 0], ends[keep, 1], mids[keep], keep % len(cells)


def _write_msh(path, x, cells):
    """The mesh as a gmsh ``.msh`` (6-node triangles in physical surface 1, the boundary as
    3-node lines in the groups LOWER and UPPER, as ``disc_mesh.write_msh`` has them), by
    gmsh's API on rank 0."""
    if COMM.rank == 0:
        import gmsh
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("getfem")
        surf = gmsh.model.addDiscreteEntity(2)
        gmsh.model.mesh.addNodes(2, surf, np.arange(1, len(x) + 1), np.column_stack([x, 0 * x[:, 0]]).ravel())
        gmsh.model.mesh.addElementsByType(surf, 9, [], (cells + 1).ravel())
        a, b, m, _ = _boundary_arcs(cells)
        low = (x[a, 1] <= CY + 1e-9) & (x[b, 1] <= CY + 1e-9)
        for group, sel in ((disc_mesh.LOWER, low), (disc_mesh.UPPER, ~low)):
            curve = gmsh.model.addDiscreteEntity(1)
            gmsh.model.mesh.addElementsByType(curve, 8, [], (np.column_stack([a, b, m])[sel] + 1).ravel())
            gmsh.model.addPhysicalGroup(1, [curve], group)
        gmsh.model.addPhysicalGroup(2, [surf], 1)
        gmsh.write(str(path))
        gmsh.finalize()
    COMM.Barrier()
    return path


@pytest.mark.mpi
@pytest.mark.parametrize("name", sorted(TABLE_2))
def test_p2_dofs_are_the_papers(name):
    """The P2 vector dof count of each file is Table 2's, read on COMM_WORLD (1 rank, or 2
    under mpirun: then each rank must own part of the cells)."""
    msh, _ = disc_mesh.read_mesh(_file(name), R, (0.0, CY), comm=COMM)
    assert disc_mesh.p2_dofs(msh) == TABLE_2[name]
    owned = msh.topology.index_map(2).size_local
    assert min(COMM.allgather(owned)) > 0
    assert COMM.allreduce(owned, op=MPI.SUM) == len(_getfem_arrays(_file(name))[1])


def _segment_deficit(theta):
    """Circular segment of angle theta minus the parabolic one through its ends and its
    middle (Archimedes: 2/3 chord x sagitta), for R = 1: theta^5 / 960 + O(theta^7)."""
    return 0.5 * (theta - np.sin(theta)) - 4.0 / 3.0 * np.sin(theta / 2) * (1 - np.cos(theta / 2))


@pytest.mark.parametrize("name", sorted(TABLE_2))
def test_geometry_is_the_curved_disc(name):
    """Area, point A and the boundary of each file read as our disc.

    The area (1 dx, exact for a P2 geometry) equals, to 1e-12, the area inside the file's
    boundary arcs by Green's formula (each arc the parabola through its three nodes); and it
    falls short of pi R^2 by the parabolas' deficit sum_i R^2 theta_i^5 / 960 (theta_i the arc
    angles: 4.3e-6 pi R^2 for h = 4), up to what the nodes' own distance from the circle
    (delta, relative) moves the area: 2 delta pi R^2.
    """
    msh, _ = disc_mesh.read_mesh(_file(name), R, (0.0, CY), comm=COMM)
    area = COMM.allreduce(fem.assemble_scalar(compat.form(1.0 * ufl.dx(domain=msh))), op=MPI.SUM)
    x, cells = _getfem_arrays(_file(name))
    x = x + (0.0, HEIGHT)
    a, b, m, cell = _boundary_arcs(cells)
    # each boundary arc oriented as its cell's boundary runs counter-clockwise
    sign = np.sign(cross2(x[cells[cell, 1]] - x[cells[cell, 0]], x[cells[cell, 2]] - x[cells[cell, 0]]))
    half = (x[b] - x[a]) / 2
    curv = (x[a] + x[b]) / 2 - x[m]
    green = np.sum(sign * (cross2(x[m], half) + cross2(half, curv) / 3.0))   # 1/2 closed x cross dx
    assert area == pytest.approx(green, rel=1e-12)
    theta = 2 * np.arcsin(np.hypot(*(x[b] - x[a]).T) / (2 * R))
    expected = np.pi * R ** 2 - R ** 2 * np.sum(_segment_deficit(theta))
    on = np.concatenate([a, b, m])
    delta = np.max(np.abs(np.hypot(x[on, 0], x[on, 1] - CY) / R - 1))
    assert abs(area - expected) <= (2 * delta + 1e-12) * np.pi * R ** 2, (area, expected, delta)
    assert 0 < np.pi * R ** 2 - area <= np.pi * R ** 2 * (np.max(theta) ** 4 / 480 * 1.01 + 2 * delta)
    # point A: the lowest boundary vertex, at (0, HEIGHT) above the foundation y = 0
    assert disc.lowest_boundary_vertex(msh, 0.0, 1e-8 * R) == (0.0, HEIGHT)
    # every boundary vertex of the dolfinx mesh on the circle (the reader's CIRCLE_RTOL)
    msh.topology.create_connectivity(1, 2)
    verts = dmesh.locate_entities_boundary(msh, 0, lambda p: np.full(p.shape[1], True))
    p = dmesh.compute_midpoints(msh, 0, verts)
    err = np.abs(np.hypot(p[:, 0], p[:, 1] - CY) / R - 1)
    assert COMM.allreduce(float(err.max(initial=0.0)), op=MPI.MAX) <= disc_mesh.CIRCLE_RTOL
    assert COMM.allreduce(len(verts), op=MPI.SUM) >= len(a)    # ghosts may count twice


@pytest.mark.filterwarnings("ignore::sdm_dolfinx.run.result.BoundaryGapWarning")
def test_run_agrees_with_the_same_mesh_as_msh(mpi_tmp_path):
    """``disc --mesh disc_P2_h4.mesh`` and the same nodes and triangles written by gmsh (half
    of them clockwise, as in the file: the package's reader turns those) run the same disc:
    two routes to one mesh. 20 steps of 0.8 ms (Table 2's dt) reach the impact at ~10 ms.

    The cells' orientation and so the dof numbering differ: every sum over the 622 dofs runs
    in another order (round-off ~ N eps of its terms), which the energy's cancellations
    (kinetic against gravity) amplify; we allow 100 N eps = 1.4e-11 of each column's scale."""
    x, cells = _getfem_arrays(_file("disc_P2_h4.mesh"))
    msh_file = _write_msh(mpi_tmp_path / "disc_P2_h4.msh", x + (0.0, HEIGHT), cells)
    opts = dict(pair="P2/P1", dt=8e-4, T=0.016, comm=COMM)
    ours = simulate("disc", {"mesh_file": _file("disc_P2_h4.mesh")}, **opts).timeseries
    gmsh = simulate("disc", {"mesh_file": msh_file}, **opts).timeseries
    assert ours["contact_force"].max() > 0
    np.testing.assert_array_equal(ours["n_active"], gmsh["n_active"])
    for c in ("energy", "kinetic", "u_probe", "lambda_probe", "contact_force", "momentum_y"):
        scale = np.max(np.abs(ours[c]))
        np.testing.assert_allclose(ours[c], gmsh[c], rtol=0, atol=100 * 622 * np.finfo(float).eps * scale, err_msg=c)


def cross2(a, b):
    """The z-component of the cross product of 2-vectors (rows): numpy 2 deprecates np.cross of 2-vectors."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _map_points(lines, f):
    """The file's lines with every point (x, y) replaced by f(x, y)."""
    def one(line):
        t = line.split()
        if t[:1] != ["POINT"]:
            return line
        x, y = f(float(t[2]), float(t[3]))
        return f"  POINT  {t[1]}  {float(x)!r}  {float(y)!r}\n"     # numpy 2's repr is np.float64(...)
    return "".join(one(line) for line in lines)


def _bad_files(folder):
    """name -> (path, the words its one-line error must contain), written on rank 0."""
    text = _file("disc_P2_h4.mesh").read_text()
    lines = text.splitlines(keepends=True)
    k = next(i for i, s in enumerate(lines) if s.startswith("CONVEX 7 "))
    assert lines[k].split()[3:] == ["26", "103", "18", "104", "86", "27"]      # m01 = 103, m12 = 86
    x, _ = _getfem_arrays(_file("disc_P2_h4.mesh"))
    far = x[27] + 2 * (x[27] - (x[26] + x[18]) / 2)          # midpoint 103 of 26-18 beyond vertex 27
    convex7 = lambda line: "".join(lines[:k] + [line] + lines[k + 1:])          # noqa: E731
    bad = {"truncated": (text[:len("".join(lines[:k + 1])) - 6], [f":{k + 1}: cannot read", "CONVEX 7"]),
           "cut": (text[:len("".join(lines[:60]))], ["ends (line 60) before 'END POINTS LIST'"]),
           "unknown-type": (convex7("CONVEX 7    'GT_PK(2,1)'      18  27  19\n"),
                            [f":{k + 1}: convex 7 is 'GT_PK(2,1)'"]),
           "radius-25": (_map_points(lines, lambda x, y: (1.25 * x, 1.25 * y)),
                         ["not the disc of radius 20 centred at (0, 30)"]),
           # y - 20 times 0.995: the bounding box within 1 %, the boundary 0.5 % off the circle
           "ellipse": (_map_points(lines, lambda x, y: (x, 20 + 0.995 * (y - 20))),
                       ["the boundary is not the circle of radius 20 mm centred at (0, 30)"]),
           # edge 18-27 has midpoint 86 in CONVEX 0; CONVEX 7 gives it node 88
           "non-conforming": (convex7("CONVEX 7    'GT_PK(2,2)'      26  103  18  104  88  27\n"),
                              ["two cells give an edge different midpoint nodes"]),
           "folded": (_map_points(lines, lambda x_, y_: tuple(far) if np.allclose((x_, y_), x[103]) else (x_, y_)),
                      ["is folded or degenerate"])}
    paths = {}
    for name, (content, words) in bad.items():
        paths[name] = (folder / f"{name}.mesh", words)
        if COMM.rank == 0:
            paths[name][0].write_text(content)
    COMM.Barrier()
    return paths


def test_bad_files_are_refused_in_one_line(mpi_tmp_path):
    """A truncated file (cut inside a line, or between lines), an unknown convex type, a disc
    of radius 25, an ellipse, an edge with two midpoints and a folded cell: MeshError on every
    rank, naming the file (and the line)."""
    for name, (path, words) in _bad_files(mpi_tmp_path).items():
        with pytest.raises(disc_mesh.MeshError) as e:
            disc.problem(mesh_file=path, comm=COMM)
        msg = str(e.value)
        assert "\n" not in msg and msg.startswith(str(path)), msg
        for w in words:
            assert w in msg, (name, msg)


@pytest.mark.skipif(COMM.size > 1, reason="starts its own python (not under mpirun)")
def test_bad_files_from_the_command_line(mpi_tmp_path):
    """The command line: non-zero exit, one line on stderr, no traceback, nothing written."""
    for name, (path, words) in _bad_files(mpi_tmp_path).items():
        out = mpi_tmp_path / f"out-{name}"
        p = subprocess.run([sys.executable, "-m", "sdm_dolfinx", "disc", "--mesh", str(path), "--T", "0.001",
                            "--out", str(out)], capture_output=True, text=True, timeout=300)
        assert p.returncode != 0, (name, p.stderr)
        assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr, (name, p.stderr)
        assert all(w in p.stderr for w in words), (name, p.stderr)
        assert not out.exists()
