"""``disc --mesh FILE``: a mesh whose boundary is not the disc's circle is refused in one line
(its bounding box alone does not tell a square or an ellipse from the disc)."""
from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli
from sdm_dolfinx.problems import disc_mesh

COMM = MPI.COMM_WORLD
R, HEIGHT = 20.0, 10.0                  # the disc's defaults (mm): centre (0, 30)
CENTRE = (0.0, R + HEIGHT)


def _write_gmsh(path, shape, h=5.0):
    """A triangle mesh of ``shape`` (``square``: the disc's bounding box; ``ellipse``: a
    curve through the circle's four extreme points, bulging between them) written by gmsh on
    rank 0. gmsh 4.8 cannot tell whether someone else opened it: we open and close it here."""
    if COMM.rank == 0:
        import gmsh
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(shape)
        cx, cy = CENTRE
        if shape == "square":
            surf = gmsh.model.occ.addRectangle(cx - R, cy - R, 0.0, 2 * R, 2 * R)
        else:   # a superellipse |x|^4 + |y|^4 = R^4 as a spline: same bounding box, not the circle
            t = np.linspace(0.0, 2 * np.pi, 65)[:-1]
            c, s = np.cos(t), np.sin(t)
            pts = [gmsh.model.occ.addPoint(cx + R * np.sign(a) * abs(a) ** 0.5, cy + R * np.sign(b) * abs(b) ** 0.5,
                                           0.0) for a, b in zip(c, s)]
            curve = gmsh.model.occ.addSpline(pts + [pts[0]])
            surf = gmsh.model.occ.addPlaneSurface([gmsh.model.occ.addCurveLoop([curve])])
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [surf], 1)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
        gmsh.finalize()
    COMM.Barrier()
    return path


@pytest.mark.parametrize("shape", ["square", "ellipse"])
def test_mesh_that_is_not_the_disc_is_refused(shape, mpi_tmp_path, capsys):
    path = _write_gmsh(mpi_tmp_path / f"{shape}.msh", shape)
    out = mpi_tmp_path / "never"
    assert cli.main(["disc", "--mesh", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert f"{path}: the boundary is not the circle of radius 20 mm centred at (0, 30)" in err, err
        assert "relative tolerance 1e-06" in err, err
    assert not out.exists()
    with pytest.raises(disc_mesh.MeshError, match="is not the circle"):
        disc_mesh.read_mesh(path, R, CENTRE, comm=COMM)


def test_the_disc_written_by_gmsh_is_accepted(mpi_tmp_path):
    """The level-1 disc written to a file (boundary vertices on the circle to ~1e-16) is read."""
    path = mpi_tmp_path / "disc.msh"
    if COMM.rank == 0:
        disc_mesh.write_msh(path, disc_mesh.LEVELS[1], radius=R, centre=CENTRE)
    COMM.Barrier()
    msh, ft = disc_mesh.read_mesh(path, R, CENTRE, comm=COMM)
    assert msh.topology.index_map(2).size_global > 50
    assert COMM.allreduce(len(ft.values), op=MPI.SUM) > 0


def test_too_small_mesh_size_is_refused_before_gmsh():
    """h below radius / 1000 would ask gmsh for millions of triangles (or hang it): refused."""
    with pytest.raises(disc_mesh.MeshError, match=r"mesh size h = 1e-300 mm is below radius / 1000 = 0\.02 mm"):
        disc_mesh.make_mesh(1e-300, radius=R, centre=CENTRE, comm=COMM)
    assert disc_mesh.estimate_mesh(disc_mesh.LEVELS[6], R)["cells"] == pytest.approx(128e3, rel=0.1)
