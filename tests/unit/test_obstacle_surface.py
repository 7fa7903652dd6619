"""The obstacles' surfaces drawn and written (sdm_dolfinx/obstacles/surface.py) lie on the obstacles at
the time asked, within the box asked: closed forms (a plane's points satisfy (x - p).n = s(t).n, a
sphere's and a cylinder's vertices lie at their radius, a clipped plane covers the box's section)."""
import numpy as np
import pytest

from sdm_dolfinx.obstacles import Ball, Cylinder, HalfSpace, Wedge
from sdm_dolfinx.obstacles.surface import clip_triangles, enlarged_box, mesh, surface

LO, HI = np.array([-1.0, -2.0, -1.5]), np.array([3.0, 2.0, 2.5])
EPS = 1e-12


def _inside(p, lo=LO, hi=HI, tol=1e-12):
    return np.all((p >= lo - tol) & (p <= hi + tol))


def _strictly_inside(p, lo=LO, hi=HI):
    """The rows of p not on the box's faces (where a clipped facet ends on a chord)."""
    return np.all((p > lo + 1e-9) & (p < hi - 1e-9), axis=1)


def _area(tri):
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()


def test_a_moving_plane_is_where_its_motion_puts_it_and_covers_the_box():
    """HalfSpace through p with normal n moved by s(t): every point x has (x - p).n = s(t).n; the plane
    z = p_z + s_z(t) cuts the box in its whole section (area (hi - lo)_x (hi - lo)_y)."""
    s = lambda t: np.array([0.3 * t, -0.1, 0.7 * t * t])                     # noqa: E731
    p, n = np.array([0.2, 0.1, -0.4]), np.array([0.0, 0.0, 1.0])
    ob = HalfSpace(p, n, motion=s)
    for t in (0.0, 0.5, 1.3):
        tri = surface(ob, t, (LO, HI))
        x = tri.reshape(-1, 3)
        assert len(tri) and _inside(x)
        assert np.max(np.abs((x - p) @ n - s(t) @ n)) <= EPS
        assert _area(tri) == pytest.approx((HI - LO)[0] * (HI - LO)[1], rel=1e-12)
    tilted = HalfSpace(p, (0.3, -0.2, 1.0), motion=s)
    x = surface(tilted, 0.8, (LO, HI)).reshape(-1, 3)
    assert len(x) and _inside(x)
    assert np.max(np.abs((x - p) @ tilted.normal - s(0.8) @ tilted.normal)) <= EPS


def test_a_sphere_and_a_cylinder_lie_at_their_radius():
    """Ball centre c moved by s(t): vertices at |x - c - s(t)| = R; a cylinder rotating about e_z through q
    (a cam): its points at distance R from its axis rotated by omega t about q (where the box cuts a facet
    across, within the facets' sag R (1 - cos(pi/48)))."""
    s = lambda t: np.array([0.5 * t, 0.0, -0.2 * t])                         # noqa: E731
    ball = Ball((1.0, 0.0, 0.5), 0.9, motion=s)
    for t in (0.0, 1.0):
        x = surface(ball, t, (LO, HI)).reshape(-1, 3)
        r = np.linalg.norm(x - (ball.centre + s(t)), axis=1)
        assert np.max(np.abs(r - 0.9)) <= 1e-12                              # the sphere is inside the box
        assert _inside(x)
    q, omega, t = np.array([1.0, 0.0, 0.0]), 0.7, 0.9
    cyl = Cylinder((1.0, 0.5, 0.0), (1.0, 0.0, 0.0), 0.6, rotation=(q, omega))
    x = surface(cyl, t, (LO, HI)).reshape(-1, 3)
    a = np.array([np.cos(omega * t), np.sin(omega * t), 0.0])               # the axis, rotated
    c = q + np.array([[np.cos(omega * t), -np.sin(omega * t), 0], [np.sin(omega * t), np.cos(omega * t), 0],
                      [0, 0, 1]]) @ (cyl.point - q)
    d = (x - c) - np.outer((x - c) @ a, a)
    r = np.linalg.norm(d, axis=1)
    on = np.abs(r - 0.6) <= 1e-12                   # the facets' edges along the axis are on the cylinder
    assert on.sum() >= 0.4 * len(r)
    assert np.max(np.abs(r - 0.6)) <= 0.6 * (1 - np.cos(np.pi / 48)) + 1e-12      # a facet cut across
    assert _inside(x)


def test_a_wedge_is_its_two_faces():
    """Every point of a wedge's surface is on it: phi = 0 (its own signed distance) to round-off."""
    w = Wedge((1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (-1.0, 1.0, 0.0), motion=lambda t: (0.0, 0.0, t))
    x = surface(w, 0.4, (LO, HI)).reshape(-1, 3)
    assert len(x) and _inside(x)
    phi, _ = w.distance(x.T, 0.4)
    assert np.max(np.abs(phi)) <= 1e-12


def test_in_2d_the_outlines_and_what_is_not_drawn():
    """A box without z extent: segments of the outline (a bowl's circle: points at its radius, except
    where the box cuts a segment); a non-planar shape is named in ``missing``, and so is an object that is
    not an Obstacle."""
    lo, hi = np.array([-3.0, -1.0, 0.0]), np.array([3.0, 2.0, 0.0])
    bowl = Ball((0.0, 3.0), 4.0, inside=True)

    class Own:
        def distance(self, x, t=0.0):
            return x[1], np.zeros_like(x)

    m = mesh([bowl, HalfSpace((0, 0, 0), (0, 0.2, 1.0)), Own()], 0.0, (lo, hi))
    assert m["cells"].shape[1] == 2 and set(m["which"]) == {0}
    assert m["missing"] == ["half-space (obstacle 1)", "Own (obstacle 2)"]
    x = m["points"]
    assert _inside(x, lo, hi)
    inner = _strictly_inside(x[:, :2], lo[:2], hi[:2])
    assert inner.sum() > 10
    assert np.max(np.abs(np.linalg.norm(x[inner] - [0.0, 3.0, 0.0], axis=1) - 4.0)) <= 1e-12
    assert np.all(x[:, 2] == 0.0)


def test_clipping_keeps_the_part_in_the_box():
    """A triangle half in the box: the clipped area is the part inside (closed form)."""
    tri = np.array([[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]]])
    out = clip_triangles(tri, np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0]))
    assert _area(out) == pytest.approx(1.0 - 0.0, rel=1e-14)                  # the unit square minus nothing
    out = clip_triangles(tri, np.array([-1.0, -1.0, -1.0]), np.array([1.5, 1.5, 1.0]))
    assert _area(out) == pytest.approx(2.0 - 2 * 0.125, rel=1e-14)            # the triangle minus two corners
    assert len(clip_triangles(tri + 5.0, np.array([-1.0] * 3), np.array([1.0] * 3))) == 0


def test_the_enlarged_box():
    lo, hi = enlarged_box((0.0, 0.0, 0.0), (2.0, 1.0, 0.0), 1.5)
    assert lo.tolist() == [-2.0, -2.5, 0.0] and hi.tolist() == [4.0, 3.5, 0.0]
    lo, hi = enlarged_box((0.0, 0.0, 0.0), (2.0, 1.0, 1.0), 0.5)
    assert lo.tolist() == [0.0, -0.5, -0.5] and hi.tolist() == [2.0, 1.5, 1.5]


def test_a_surface_mesh_is_its_triangles_moved(tmp_path):
    """The unit tetrahedron of a .msh, translated by s(t): its four triangles (total area 3/2 + sqrt(3)/2)
    at their place, every point on the surface (phi = 0); cut by a box, the part inside."""
    from sdm_dolfinx.obstacles import SurfaceMesh
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    path = tmp_path / "tet.msh"
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n")
        f.writelines(f"{i + 1} {float(x)!r} {float(y)!r} {float(z)!r}\n" for i, (x, y, z) in enumerate(p))
        f.write("$EndNodes\n$Elements\n4\n")
        f.writelines(f"{i + 1} 2 2 0 1 {a + 1} {b + 1} {c + 1}\n" for i, (a, b, c) in
                     enumerate([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))
        f.write("$EndElements\n")
    tet = SurfaceMesh(path, motion=lambda t: (t, 0.0, -t))
    tri = surface(tet, 0.5, (LO, HI))
    assert _area(tri) == pytest.approx(1.5 + np.sqrt(3) / 2, rel=1e-14)
    assert np.max(np.abs(tet.distance(tri.reshape(-1, 3).T, 0.5)[0])) <= 1e-14
    assert sorted(map(tuple, np.unique(tri.reshape(-1, 3), axis=0))) == \
        sorted(map(tuple, p + [0.5, 0.0, -0.5]))
    half = surface(tet, 0.5, (LO, np.array([3.0, 2.0, 0.0])))            # the part below z = 0
    assert np.all(half[:, :, 2] <= 0.0) and 0 < _area(half) < 1.5 + np.sqrt(3) / 2
