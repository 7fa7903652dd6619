"""Rigid obstacles as signed distances (sdm_dolfinx.obstacles), against closed forms.

Each expectation is the shape's defining formula (docs/obstacles.md), evaluated by hand at
chosen points, or a property every signed distance has: |grad phi| = 1 wherever it is
differentiable (checked by central differences, step 1e-6, tolerance 1e-6: the truncation
error is O(h^2 / curvature radius), round-off O(1e-16 / h)), phi(x, t) = phi_0(x - s(t)) for a
translated obstacle, and a polygon/polyhedron read from a .msh file agreeing with the smooth
shape it approximates to within its sagitta. Pure numpy: no MPI, the same on every rank.
"""
import json
import math

import numpy as np
import pytest

from sdm_dolfinx import obstacles as ob
from sdm_dolfinx.obstacles import ObstacleError

RNG = np.random.default_rng(20261127)
H = 1e-6                       # central-difference step
FD_TOL = 1e-6


def pts(*p):
    """Points given as tuples (2 or 3 numbers) -> dolfinx's layout (3, n)."""
    return np.array([tuple(q) + (0.0,) * (3 - len(q)) for q in p], dtype=float).T


def one_line(exc):
    msg = str(exc.value)
    assert msg and "\n" not in msg, msg
    return msg


def fd_gradient(o, x, t=0.0):
    g = np.zeros_like(x)
    for k in range(3):
        e = np.zeros((3, 1))
        e[k] = H
        g[k] = (o.distance(x + e, t)[0] - o.distance(x - e, t)[0]) / (2 * H)
    return g


def check_normal_is_gradient(o, x, t=0.0):
    """|normal| = 1 and normal = grad phi (central differences) at the points x."""
    phi, n = o.distance(x, t)
    assert np.all(np.isfinite(phi)) and np.all(np.isfinite(n))
    assert np.allclose(np.linalg.norm(n, axis=0), 1.0, atol=1e-14)
    assert np.max(np.abs(n - fd_gradient(o, x, t))) < FD_TOL


# -- half-space -------------------------------------------------------------------------------------

def test_half_space_is_the_plane_distance_in_any_orientation():
    # an inclined plane through p = (1, 2, 3) with normal (1, 2, 2)/3: phi = (x - p).n
    o = ob.HalfSpace((1, 2, 3), (1, 2, 2))
    n = np.array([1, 2, 2]) / 3
    x = pts((1, 2, 3), (1 + 3, 2 + 6, 3 + 6), (0, 0, 0), (1 - 2, 2 + 1, 3))     # on, 9 outside, inside, on
    phi, normal = o.distance(x)
    assert np.allclose(phi, [0, 9, -(1 + 4 + 6) / 3, 0], atol=1e-14)
    assert np.allclose(normal, n[:, None])
    check_normal_is_gradient(o, RNG.uniform(-5, 5, (3, 20)))


def test_half_plane_in_2d():
    # the floor y >= -1 of a 2-D problem: phi = y + 1, normal e_y, normal[2] == 0
    o = ob.HalfSpace((0, -1), (0, 5))
    phi, n = o.distance(pts((3, -1), (0, 1), (2, -3)))
    assert np.allclose(phi, [0, 2, -2]) and np.allclose(n, [[0], [1], [0]])
    assert o.planar and not ob.HalfSpace((0, 0, 0), (0, 1, 1)).planar


# -- ball -------------------------------------------------------------------------------------------

def test_ball_outside_and_inside():
    c, R = np.array([1.0, -2.0, 0.5]), 2.0
    x = pts(tuple(c + [3, 4, 0]), tuple(c + [0, 0, R]), tuple(c + [1, 0, 0]), tuple(c))
    # the obstacle is the ball: phi = |x - c| - R = 5 - 2, 0, 1 - 2, -2 (at the centre, normal e_x)
    phi, n = ob.Ball(c, R).distance(x)
    assert np.allclose(phi, [3, 0, -1, -2])
    assert np.allclose(n.T, [[0.6, 0.8, 0], [0, 0, 1], [1, 0, 0], [1, 0, 0]])
    # the cavity (a bowl): the obstacle is outside the ball, phi = R - |x - c|, normal towards c
    phi, n = ob.Ball(c, R, inside=True).distance(x)
    assert np.allclose(phi, [-3, 0, 1, 2])
    assert np.allclose(n.T, [[-0.6, -0.8, 0], [0, 0, -1], [-1, 0, 0], [-1, 0, 0]])


def test_ball_normal_is_the_gradient_away_from_the_centre():
    for inside in (False, True):
        o = ob.Ball((0.3, 0.1, -0.2), 1.5, inside=inside)
        x = RNG.uniform(-3, 3, (3, 30))
        x = x[:, np.linalg.norm(x - o.centre[:, None], axis=0) > 0.1]      # the centre is a kink
        check_normal_is_gradient(o, x)


# -- cylinder ---------------------------------------------------------------------------------------

def test_cylinder_is_the_distance_to_its_axis():
    a = np.array([1.0, 1.0, 1.0]) / math.sqrt(3)
    p, R = np.array([0.0, 0.0, 1.0]), 0.5
    radial = np.array([1.0, -1.0, 0.0]) / math.sqrt(2)         # a unit vector normal to the axis
    # points p + s a + r radial: phi = r - R whatever s is (the distance to the axis line is r)
    x = np.column_stack([p + s * a + r * radial for s, r in ((0, 2), (5, 0.5), (-3, 0.2), (1, 0))])
    phi, n = ob.Cylinder(p, (2, 2, 2), R).distance(x)
    assert np.allclose(phi, [1.5, 0, -0.3, -0.5])
    assert np.allclose(n[:, :3], radial[:, None])
    assert abs(np.linalg.norm(n[:, 3]) - 1) < 1e-14 and abs(n[:, 3] @ a) < 1e-14    # on the axis: normal to it
    phi_in, n_in = ob.Cylinder(p, a, R, inside=True).distance(x)
    assert np.allclose(phi_in, -phi) and np.allclose(n_in, -n)
    y = RNG.uniform(-3, 3, (3, 30))
    d = y - p[:, None]
    y = y[:, np.linalg.norm(d - np.outer(a, a @ d), axis=0) > 0.1]       # the axis is a kink
    check_normal_is_gradient(ob.Cylinder(p, a, R), y)


# -- wedge ------------------------------------------------------------------------------------------

def _wedge_2d():
    """The 2-D wedge y <= -|x| tan(30 deg) (apex at the origin, faces at 30 deg below the horizontal,
    interior angle 120 deg): n1 = (sin 30, cos 30), n2 = (-sin 30, cos 30)."""
    s, c = 0.5, math.sqrt(3) / 2
    return ob.Wedge((0, 0), (s, c), (-s, c)), np.array([s, c, 0]), np.array([-s, c, 0])


def test_wedge_inside_is_the_larger_plane_distance():
    o, n1, n2 = _wedge_2d()
    # inside, right of the bisector x = 0: face 1 is nearer; phi = d1 = x sin30 + y cos30
    # inside, left: face 2; on the bisector: the tie, normal (n1 + n2)/|n1 + n2| = e_y
    x = pts((0.2, -1.0), (-0.2, -1.0), (0.0, -1.0))
    phi, n = o.distance(x)
    assert np.allclose(phi, [0.1 - 1 * math.sqrt(3) / 2, 0.1 - math.sqrt(3) / 2, -math.sqrt(3) / 2])
    assert np.allclose(n[:, 0], n1) and np.allclose(n[:, 1], n2) and np.allclose(n[:, 2], [0, 1, 0])


def test_wedge_outside_is_the_distance_to_a_face_or_to_the_apex():
    o, n1, n2 = _wedge_2d()
    # above face 1 (its foot 2 n1 back lies on face 1, x > 0): phi = 2, normal n1
    foot = 3 * np.array([math.cos(math.radians(30)), -0.5, 0])        # a point of face 1
    x_face = foot + 2 * n1
    # the apex region (between the two normals): the distance to the apex, normal x/|x|
    x_apex = np.array([0.1, 2.0, 0.0])
    # on face 2 (phi = 0, normal n2) and at the apex itself (phi = 0, normal (n1 + n2)/|.| = e_y)
    x_on = foot * np.array([-1, 1, 1])                # face 2 is face 1 mirrored in x = 0
    phi, n = o.distance(np.column_stack([x_face, x_apex, x_on, np.zeros(3)]))
    assert np.allclose(phi, [2, np.linalg.norm(x_apex), 0, 0], atol=1e-14)
    assert np.allclose(n[:, 0], n1) and np.allclose(n[:, 1], x_apex / np.linalg.norm(x_apex))
    assert np.allclose(n[:, 2], n2) and np.allclose(n[:, 3], [0, 1, 0])


def test_wedge_acute_and_obtuse_agree_with_a_brute_force_distance():
    # the distance from outside points to the wedge's convex region, found independently as the
    # minimum over a dense sampling of its two faces (error <= the sampling step 1e-3)
    for angle in (40.0, 100.0, 170.0):                      # the interior angle, in degrees
        half = math.radians(angle) / 2
        n1 = np.array([math.cos(half), -math.sin(half), 0])          # faces symmetric about -e_y... rotated
        n2 = np.array([-math.cos(half), -math.sin(half), 0])
        o = ob.Wedge((0.5, 0.2), n1, n2)
        s = np.arange(0, 8, 1e-3)
        t1, t2 = np.array([-n1[1], n1[0], 0]), np.array([-n2[1], n2[0], 0])
        t1 *= -np.sign(t1 @ n2)
        t2 *= -np.sign(t2 @ n1)
        faces = np.concatenate([np.outer(s, t1), np.outer(s, t2)]) + [0.5, 0.2, 0]
        x = RNG.uniform(-2, 2, (3, 40)) + np.array([[0.5], [0.2], [0]])
        x[2] = 0
        phi, _ = o.distance(x)
        brute = np.min(np.linalg.norm(x.T[:, None] - faces[None], axis=2), axis=1)
        inside = (n1 @ (x - [[0.5], [0.2], [0]]) <= 0) & (n2 @ (x - [[0.5], [0.2], [0]]) <= 0)
        assert np.all(np.abs(np.abs(phi) - brute) < 1e-3) and np.all((phi < 0) == inside)
        d = np.abs(n1 @ (x - [[0.5], [0.2], [0]]) - n2 @ (x - [[0.5], [0.2], [0]]))
        check_normal_is_gradient(o, x[:, ~inside | (d > 0.01)])       # the inside bisector is a kink


def test_wedge_3d_is_invariant_along_its_edge():
    # an edge along n1 x n2: shifting a point along it changes nothing
    n1, n2 = np.array([1.0, 0, 1]), np.array([0, 1.0, 1])
    o = ob.Wedge((0, 0, 0), n1, n2)
    e = np.cross(n1, n2) / np.linalg.norm(np.cross(n1, n2))
    x = RNG.uniform(-2, 2, (3, 20))
    phi, n = o.distance(x)
    phi2, n2_ = o.distance(x + 3.7 * e[:, None])
    assert np.allclose(phi, phi2, atol=1e-13) and np.allclose(n, n2_, atol=1e-13)
    assert np.allclose(n.T @ e, 0, atol=1e-13)


# -- motion -----------------------------------------------------------------------------------------

def test_a_translated_obstacle_is_phi0_at_x_minus_s():
    s = lambda t: np.array([0.1 * t, -0.3 * t * t, 0.0])            # noqa: E731
    fixed = ob.Ball((0, 0, 0), 1.0)
    moving = ob.Ball((0, 0, 0), 1.0, motion=s)
    x = RNG.uniform(-2, 2, (3, 10))
    for t in (0.0, 0.7, 2.0):
        phi, n = moving.distance(x, t)
        phi0, n0 = fixed.distance(x - s(t)[:, None])
        assert np.allclose(phi, phi0, atol=1e-15) and np.allclose(n, n0, atol=1e-15)
    assert moving.moves and not fixed.moves
    # velocity: s'(t) = (0.1, -0.6 t, 0) by the central difference (error O(h^2 s''') = 0 here, plus round-off)
    assert np.allclose(moving.velocity(x, 2.0), [[0.1], [-1.2], [0]], atol=1e-8)
    assert np.array_equal(fixed.velocity(x, 2.0), np.zeros((3, 10)))
    given = ob.Ball((0, 0, 0), 1.0, motion=s, motion_velocity=lambda t: (0.1, -0.6 * t))
    assert np.allclose(given.velocity(x, 2.0), [[0.1], [-1.2], [0]], atol=1e-15)


def test_a_punch_whose_declared_position_is_not_s0():
    # s(0) = (0, 2, 0): at t = 0 the floor y >= 0 is already lifted to y >= 2
    o = ob.HalfSpace((0, 0), (0, 1), motion=lambda t: (0, 2 - t))
    assert np.allclose(o.distance(pts((0, 5)), 0.0)[0], [3]) and np.allclose(o.distance(pts((0, 5)), 1.5)[0], [4.5])
    assert np.allclose(o.velocity(pts((0, 5)), 1.0), [[0], [-1], [0]], atol=1e-9)


def test_a_rotating_cam():
    # a half-plane x >= 1 (obstacle x < 1) turning about c = (0, 0) at omega: at the time t its
    # boundary is the line through R(wt)(1, 0) with the normal (cos wt, sin wt)
    w = 0.8
    o = ob.HalfSpace((1, 0), (1, 0), rotation=((0, 0), w))
    x = RNG.uniform(-2, 2, (3, 10))
    x[2] = 0
    for t in (0.0, 0.5, 3.0):
        n = np.array([math.cos(w * t), math.sin(w * t), 0])
        phi, normal = o.distance(x, t)
        assert np.allclose(phi, n @ x - 1) and np.allclose(normal, n[:, None])
    # the material point at x moves at omega e_z x (x - c)
    assert np.allclose(o.velocity(x, 1.0), w * np.vstack([-x[1], x[0], 0 * x[0]]))
    assert o.moves and o.describe()["motion"]["rotation"] == {"centre": [0, 0, 0], "omega": w}


def test_motion_moves_the_material_points_along_the_velocity():
    # d/dt phi(x(t), t) = 0 for a material point x(t) = s(t) + c + R(wt)(X - c): checked through
    # phi(x + v dt, t + dt) - phi(x, t) = O(dt^2)
    o = ob.Wedge((0.3, 0.1), (1, 2), (-1, 1), motion=lambda t: (math.sin(t), 0.5 * t), rotation=((0.2, 0), 1.3))
    x = RNG.uniform(-2, 2, (3, 10))
    x[2] = 0
    dt = 1e-5
    drift = o.distance(x + dt * o.velocity(x, 1.0), 1.0 + dt)[0] - o.distance(x, 1.0)[0]
    assert np.max(np.abs(drift)) < 1e-8


# -- the registry and the description --------------------------------------------------------------

def test_registry_names_and_make():
    assert ob.names() == ["ball", "cylinder", "half-space", "surface-mesh", "wedge"]
    assert ob.get("ball") is ob.Ball
    o = ob.make("wedge", apex=(0, 0), normal1=(1, 1), normal2=(-1, 1))
    d = json.loads(json.dumps(o.describe()))
    assert d["kind"] == "wedge" and d["motion"] == "fixed" and d["parameters"]["apex"] == [0, 0, 0]
    m = ob.make("ball", centre=(0, 0), radius=1, motion=lambda t: (t, 0))
    assert json.loads(json.dumps(m.describe()))["motion"]["velocity"].startswith("central difference")


@pytest.mark.parametrize("kind,params,words", [
    ("sphere", {}, "unknown obstacle kind 'sphere'"),
    ("ball", {"centre": (0, 0), "radiu": 1}, "unknown parameter(s) 'radiu'"),
    ("ball", {"centre": (0, 0)}, "missing parameter(s) 'radius'"),
    ("ball", {"centre": (0, 0), "radius": 0}, "radius must be a finite number > 0"),
    ("ball", {"centre": (0, 0), "radius": -1}, "radius must be a finite number > 0"),
    ("ball", {"centre": (0, 0), "radius": float("inf")}, "radius must be a finite number > 0"),
    ("ball", {"centre": (0, 0, 0, 0), "radius": 1}, "centre must be a finite vector of 2 or 3 numbers"),
    ("ball", {"centre": (0, float("nan")), "radius": 1}, "centre must be a finite vector"),
    ("ball", {"centre": "origin", "radius": 1}, "centre must be a finite vector"),
    ("ball", {"centre": (0, 0), "radius": True}, "radius must be a finite number > 0"),
    ("ball", {"centre": (0, 0), "radius": 1, "inside": 1}, "inside must be True or False"),
    ("half-space", {"point": (0, 0), "normal": (0, 0)}, "normal must not be the zero vector"),
    ("cylinder", {"point": (0, 0), "axis": (0, 1), "radius": 1}, "a cylinder is 3-D"),
    ("cylinder", {"point": (0, 0, 0), "axis": (0, 0, 0), "radius": 1}, "axis must not be the zero vector"),
    ("wedge", {"apex": (0, 0), "normal1": (0, 1), "normal2": (0, 3)}, "parallel or opposite"),
    ("wedge", {"apex": (0, 0), "normal1": (0, 1), "normal2": (0, -1)}, "parallel or opposite"),
    ("ball", {"centre": (0, 0), "radius": 1, "motion": (1, 0)}, "motion must be None or a callable"),
    ("ball", {"centre": (0, 0), "radius": 1, "motion": lambda t: (1, 2, 3, 4)}, "motion(0.0) must be a finite"),
    ("ball", {"centre": (0, 0), "radius": 1, "motion": lambda t: (math.nan, 0)}, "motion(0.0) must be a finite"),
    ("ball", {"centre": (0, 0), "radius": 1, "motion_velocity": lambda t: (1, 0)}, "without a motion"),
    ("ball", {"centre": (0, 0), "radius": 1, "rotation": 3.0}, "rotation must be a pair"),
    ("ball", {"centre": (0, 0), "radius": 1, "rotation": ((0, 0), math.inf)}, "omega must be a finite number"),
    ("surface-mesh", {"path": "/nonexistent/obstacle.msh"}, "does not exist"),
])
def test_refusals(kind, params, words):
    with pytest.raises(ObstacleError) as e:
        ob.make(kind, **params)
    assert words in one_line(e)


def test_refusals_at_evaluation():
    o = ob.Ball((0, 0), 1.0, motion=lambda t: (0, 0) if t < 1 else (math.inf, 0))
    with pytest.raises(ObstacleError) as e:
        o.distance(pts((0, 0)), 2.0)
    assert "motion(2.0) must be a finite" in one_line(e)
    with pytest.raises(ObstacleError) as e:
        o.distance(np.zeros((2, 4)))
    assert "array (3, n)" in one_line(e)
    with pytest.raises(ObstacleError):
        ob.register("ball", ob.HalfSpace)          # its kind is 'half-space'
    assert issubclass(ObstacleError, ob.base.ProblemInputError)


# -- outlines ---------------------------------------------------------------------------------------

def test_outline_is_clipped_to_the_box():
    box = ((-1, -1, 0), (1, 1, 0))
    # the line y = 0.5 across the box: from x = -1 to x = 1
    (line,) = ob.HalfSpace((0, 0.5), (0, 1)).outline(0.0, box)
    assert np.allclose(sorted(line[:, 0]), [-1, 1]) and np.allclose(line[:, 1], 0.5)
    # a circle of radius 0.5 inside the box: whole, closed, every point on it
    (circle,) = ob.Ball((0, 0), 0.5).outline(0.0, box)
    assert np.allclose(np.linalg.norm(circle[:, :2], axis=1), 0.5) and np.allclose(circle[0], circle[-1])
    # moved by s(t) = (t, 0): at t = 0.8 the circle about (0.8, 0) leaves the box at x = 1
    pieces = ob.Ball((0, 0), 0.5, motion=lambda t: (t, 0)).outline(0.8, box)
    allp = np.concatenate(pieces)
    # (to the sampled circle's sagitta 0.5 (1 - cos(pi / 360)) = 1.9e-5: the cut ends lie on a chord)
    assert allp[:, 0].max() <= 1 + 1e-15 and allp[:, 0].max() > 1 - 1e-15
    assert np.allclose(np.linalg.norm(allp[:, :2] - [0.8, 0], axis=1), 0.5, atol=2e-5)
    # a 3-D box: no curves
    assert ob.Ball((0, 0, 0), 0.5).outline(0.0, ((-1, -1, -1), (1, 1, 1))) == []
    # the wedge's corner: one polyline through the apex
    (corner,) = ob.Wedge((0, 0), (1, 1), (-1, 1)).outline(0.0, box)
    assert any(np.allclose(p, 0) for p in corner)


# -- surface meshes ---------------------------------------------------------------------------------

def write_msh22(path, points, cells):
    """A gmsh 2.2 ASCII file with the lines (k = 2) or triangles (k = 3) ``cells`` (0-based)."""
    etype = {2: 1, 3: 2}[cells.shape[1]]
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(points))
        for i, p in enumerate(points):
            f.write("%d %r %r %r\n" % (i + 1, *map(float, p)))
        f.write("$EndNodes\n$Elements\n%d\n" % len(cells))
        for i, c in enumerate(cells):
            f.write("%d %d 2 0 1 %s\n" % (i + 1, etype, " ".join(str(v + 1) for v in c)))
        f.write("$EndElements\n")
    return path


def polygon(n, R=1.0, cw=False):
    a = 2 * np.pi * np.arange(n) / n * (-1 if cw else 1)
    p = np.column_stack([R * np.cos(a), R * np.sin(a), 0 * a])
    return p, np.column_stack([np.arange(n), (np.arange(n) + 1) % n])


def gmsh_circle(path, R, h):
    """A circle of radius R about the origin meshed by gmsh into lines of length about h, written as .msh 4.1."""
    import gmsh
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("circle")
        gmsh.model.occ.addCircle(0, 0, 0, R)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.model.mesh.generate(1)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def test_a_gmsh_circle_agrees_with_the_disc_to_its_sagitta(tmp_path):
    # the polygon lies between the circle and the circle shrunk by the sagitta R - sqrt(R^2 - (L/2)^2)
    # (L the longest chord), so |phi_mesh - phi_disc| <= that sagitta everywhere
    R = 1.0
    path = gmsh_circle(tmp_path / "circle.msh", R, 0.1)
    disc, mesh = ob.Ball((0, 0), R), ob.SurfaceMesh(path)
    L = np.linalg.norm(np.diff(mesh.points[mesh.cells], axis=1), axis=2).max()
    sagitta = R - math.sqrt(R * R - L * L / 4)
    x = RNG.uniform(-2, 2, (3, 400))
    x[2] = 0
    phi_m, n_m = mesh.distance(x)
    phi_d, _ = disc.distance(x)
    assert mesh.dim == 2 and mesh.planar and 1e-4 < sagitta < 2e-3
    assert np.max(np.abs(phi_m - phi_d)) <= sagitta * (1 + 1e-12)
    assert np.allclose(np.linalg.norm(n_m, axis=0), 1) and np.all(n_m[2] == 0)
    # the bowl: the same file with side="inside" is the disc's cavity
    phi_b, _ = ob.SurfaceMesh(path, side="inside").distance(x)
    assert np.allclose(phi_b, -phi_m)
    # the distance to a convex polygon is differentiable outside it (away from it by the step)
    out = x[:, phi_m > 1e-3]
    check_normal_is_gradient(mesh, out)
    # its outline: the polygon's lines (every point on the circle to the sagitta), clipped to the box
    lines = mesh.outline(0.0, ((-2, -2, 0), (0, 2, 0)))
    allp = np.concatenate(lines)
    assert allp[:, 0].max() <= 0 and np.all(np.abs(np.linalg.norm(allp, axis=1) - R) <= sagitta)
    d = json.loads(json.dumps(mesh.describe()))
    assert d["parameters"]["elements"] == len(mesh.cells) and len(d["parameters"]["sha256"]) == 64


@pytest.mark.parametrize("cw", [False, True])
def test_orientation_convention_and_side(tmp_path, cw):
    # the square polygon (n = 4, R = sqrt 2: vertices (+-1, +-1)) is the square |x|, |y| <= 1 whose
    # signed distance is known exactly: inside max(|x|, |y|) - 1, outside |max(|x| - 1, |y| - 1, 0)|
    p, c = polygon(4, math.sqrt(2), cw)
    p = np.array([[math.cos(a), math.sin(a), 0] for a in np.arctan2(p[:, 1], p[:, 0])]) * math.sqrt(2)
    path = write_msh22(tmp_path / "square.msh", p, c)
    x = RNG.uniform(-3, 3, (3, 300))
    x[2] = 0
    rot = np.array([[1, -1, 0], [1, 1, 0], [0, 0, math.sqrt(2)]]) / math.sqrt(2)   # vertices at 45 deg: rotate
    y = rot.T @ x
    q = np.abs(y[:2]) - 1
    exact = np.where(np.all(q <= 0, axis=0), q.max(axis=0), np.linalg.norm(np.maximum(q, 0), axis=0))
    assert np.allclose(ob.SurfaceMesh(path).distance(x)[0], exact, atol=1e-14)       # whatever the file's order
    assert np.allclose(ob.SurfaceMesh(path, side="inside").distance(x)[0], -exact, atol=1e-14)
    # side="normals" takes the file's order: counter-clockwise = the obstacle on the left = the solid square
    assert np.allclose(ob.SurfaceMesh(path, side="normals").distance(x)[0], exact * (-1 if cw else 1), atol=1e-14)


def test_concave_corner_signs(tmp_path):
    # an L-shaped obstacle (the square [0, 2]^2 without [1, 2]^2), counter-clockwise; near the
    # reflex corner (1, 1) the sign must follow point-in-L, on both sides of it
    p = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]], dtype=float)
    c = np.column_stack([np.arange(6), (np.arange(6) + 1) % 6])
    o = ob.SurfaceMesh(write_msh22(tmp_path / "L.msh", p, c), side="normals")
    x = pts((2.1, 1.1), (1.5, 1.02), (0.9, 0.9), (1.0, 1.0), (1.2, 0.9), (0.95, 1.5), (1.1, 1.3))
    phi, n = o.distance(x)
    # (2.1, 1.1): beyond the convex corner (2, 1): +0.1 sqrt 2, normal (1, 1)/sqrt 2;
    # (1.5, 1.02): in the notch above the edge y = 1: +0.02; (0.9, 0.9): inside, the reflex corner
    # (1, 1) nearest: -0.1 sqrt 2, normal towards it; the reflex corner itself: 0, normal the
    # pseudo-normal (1, 1)/sqrt 2; (1.2, 0.9): inside under y = 1: -0.1; (0.95, 1.5): inside, left of
    # x = 1: -0.05 = x - 1, normal e_x (grad phi); (1.1, 1.3): in the notch right of x = 1: +0.1, normal e_x
    assert np.allclose(phi, [0.1 * math.sqrt(2), 0.02, -0.1 * math.sqrt(2), 0, -0.1, -0.05, 0.1], atol=1e-14)
    assert np.allclose(n[:, 6], [1, 0, 0]) and np.allclose(n[:, 1], [0, 1, 0]) and np.allclose(n[:, 5], [1, 0, 0])
    assert np.allclose(n[:, 0], [1 / math.sqrt(2), 1 / math.sqrt(2), 0])
    assert np.allclose(n[:, 2], [1 / math.sqrt(2), 1 / math.sqrt(2), 0])    # grad phi: towards the corner
    assert np.allclose(n[:, 3], [1 / math.sqrt(2), 1 / math.sqrt(2), 0])    # on it: the pseudo-normal


def gmsh_box(path, h):
    import gmsh
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("box")
        gmsh.model.occ.addBox(-1, -1, -1, 2, 2, 2)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def test_a_triangulated_cube_is_the_box_distance(tmp_path):
    # a cube [-1, 1]^3 triangulated by gmsh (flat faces: exact, whatever the triangles): phi is the
    # box's signed distance, outside |max(|x| - 1, 0)| (faces, edges and corners: the pseudo-normals'
    # convex cases), inside max_i(|x_i|) - 1; side="inside" (a box-shaped cavity: concave edges
    # and corners) the opposite
    o = ob.SurfaceMesh(gmsh_box(tmp_path / "box.msh", 0.7))
    x = RNG.uniform(-2.5, 2.5, (3, 300))
    q = np.abs(x) - 1
    exact = np.where(np.all(q <= 0, axis=0), q.max(axis=0), np.linalg.norm(np.maximum(q, 0), axis=0))
    phi, n = o.distance(x)
    assert o.dim == 3 and not o.planar
    assert np.allclose(phi, exact, atol=1e-13)
    assert np.allclose(ob.SurfaceMesh(tmp_path / "box.msh", side="inside").distance(x)[0], -exact, atol=1e-13)
    # grad phi by central differences, inside too (away from the kinks: the planes |x_i| = |x_j| inside)
    top = np.sort(np.abs(x), axis=0)
    check_normal_is_gradient(o, x[:, (phi > 0) | (top[2] - top[1] > 0.01)])
    corner = pts((1.5, 1.5, 1.5), (1.5, 1.5, 0.2), (0, 0, 1.5), (1, 1, 1))
    phi, n = o.distance(corner)
    assert np.allclose(phi, [math.sqrt(0.75), math.sqrt(0.5), 0.5, 0])
    assert np.allclose(n[:, :3].T, [[1 / math.sqrt(3)] * 3, [1 / math.sqrt(2)] * 2 + [0], [0, 0, 1]])
    assert np.allclose(n[:, 3], 1 / math.sqrt(3))       # at the corner: the angle-weighted pseudo-normal


def test_surface_mesh_refusals(tmp_path):
    p, c = polygon(8)
    cases = [
        (write_msh22(tmp_path / "open.msh", p, c[:-1]), {}, "not closed"),
        (write_msh22(tmp_path / "flip.msh", p, np.vstack([c[:4], c[4:, ::-1]])), {}, "not consistently oriented"),
        (write_msh22(tmp_path / "lifted.msh", p + [0, 0, 1], c), {}, "must lie in the plane z = 0"),
        (write_msh22(tmp_path / "degenerate.msh", np.vstack([p, p[:1]]), np.vstack([c, [[0, 8]]])),
         {"side": "normals"}, "degenerate"),
        (write_msh22(tmp_path / "square.msh", p, c), {"side": "left"}, "side must be one of"),
        (write_msh22(tmp_path / "tri2d.msh", p[:3], np.array([[0, 1, 2]])), {}, "(a 2-D domain?)"),
        (write_msh22(tmp_path / "tri2d_lines.msh", p[:3], np.array([[0, 1, 2]])), {"dim": 2}, "no line elements"),
    ]
    (tmp_path / "empty.msh").write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n0\n$EndNodes\n"
                                        "$Elements\n0\n$EndElements\n")
    (tmp_path / "binary.msh").write_text("$MeshFormat\n4.1 1 8\n$EndMeshFormat\n")
    (tmp_path / "junk.msh").write_text("hello\n")
    full = write_msh22(tmp_path / "whole.msh", p, c).read_text()
    (tmp_path / "cut.msh").write_text(full[:full.index("$EndElements")])               # a truncated file
    cases += [(tmp_path / "empty.msh", {}, "no line elements"), (tmp_path / "binary.msh", {}, "binary?"),
              (tmp_path / "junk.msh", {}, "not a gmsh .msh file"),
              (tmp_path / "cut.msh", {}, "no complete $Nodes or $Elements section")]
    for path, params, words in cases:
        with pytest.raises(ObstacleError) as e:
            ob.SurfaceMesh(path, **params)
        assert words in one_line(e), (path.name, one_line(e))
    # an open curve is taken with side="normals"
    assert np.allclose(ob.SurfaceMesh(tmp_path / "open.msh", side="normals").distance(pts((0, 0)))[0],
                       [-math.cos(math.pi / 8)])


def test_the_prefilter_finds_the_brute_force_closest_point(tmp_path):
    # a sphere (radius 1) triangulated by gmsh: |phi| must equal the least distance to ALL its triangles
    # (the KD-tree and disc-bound prefilter may only skip elements that cannot be nearer), near and far
    # (far points have many near-equidistant triangles); the sign is the sphere's wherever the point is
    # farther from the sphere than the triangles' largest deviation from it
    import gmsh
    from sdm_dolfinx.obstacles import closest
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.occ.addSphere(0, 0, 0, 1)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(tmp_path / "sphere.msh"))
    finally:
        gmsh.finalize()
    o = ob.SurfaceMesh(tmp_path / "sphere.msh")
    d = RNG.normal(size=(3, 200))
    x = d / np.linalg.norm(d, axis=0) * RNG.uniform(0.0, 4.0, 200)
    phi, _ = o.distance(x)
    m = len(o.cells)
    corners = [np.tile(o.points[o.cells[:, k]], (200, 1)) for k in range(3)]
    q, _ = closest.on_triangles(np.repeat(x.T, m, axis=0), *corners)
    brute = np.linalg.norm(np.repeat(x.T, m, axis=0) - q, axis=1).reshape(200, m).min(axis=1)
    assert np.allclose(np.abs(phi), brute, rtol=0, atol=1e-14)
    c = o.points[o.cells].mean(axis=1)
    deviation = 1 - np.min(np.abs(np.einsum("ij,ij->i", c, o.normals)))     # 1 - the least plane distance
    sphere = np.linalg.norm(x, axis=0) - 1
    clear = np.abs(sphere) > deviation
    assert 0 < deviation < 0.05 and np.all(np.sign(phi[clear]) == np.sign(sphere[clear]))


def test_a_failing_motion_is_refused_in_one_line():
    # a motion defined for t >= 0 only: the central difference at t = 0 needs s(-h); the message says
    # why and what to give instead; with motion_velocity the obstacle is accepted
    s = lambda t: (0.0, -math.sqrt(t))                                  # noqa: E731
    with pytest.raises(ObstacleError) as e:
        ob.Ball((0, 0), 1.0, motion=s)
    assert "motion(-1e-06) raised ValueError" in one_line(e) and "give motion_velocity" in one_line(e)
    o = ob.Ball((0, 0), 1.0, motion=s, motion_velocity=lambda t: (0.0, -0.5 / math.sqrt(t) if t > 0 else 0.0))
    assert np.allclose(o.distance(pts((0, 0)), 4.0)[0], [1.0])           # the centre at (0, -2): |x - c| - 1


def test_no_points():
    for o in (ob.HalfSpace((0, 0), (0, 1)), ob.Ball((0, 0), 1), ob.Cylinder((0, 0, 0), (0, 0, 1), 1),
              ob.Wedge((0, 0), (1, 1), (-1, 1))):
        phi, n = o.distance(np.zeros((3, 0)))
        assert phi.shape == (0,) and n.shape == (3, 0) and o.velocity(np.zeros((3, 0)), 0.0).shape == (3, 0)


def test_a_tetrahedron_and_its_3d_refusals(tmp_path):
    # the unit tetrahedron (0, e_x, e_y, e_z) with outward (counter-clockwise) triangles; its signed
    # distance at chosen points: below the face z = 0 by 0.5 (normal -e_z), inside near the origin
    # (-0.1: the nearest of the three coordinate faces), beyond the vertex e_z (distance 1, normal e_z),
    # beyond the slanted face x + y + z = 1 (distance (s - 1)/sqrt 3 along (1, 1, 1)/sqrt 3)
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    tri = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    o = ob.SurfaceMesh(write_msh22(tmp_path / "tet.msh", p, tri), side="normals")
    phi, n = o.distance(pts((0.2, 0.2, -0.5), (0.1, 0.15, 0.2), (0, 0, 2), (0.5, 0.5, 0.5)))
    assert np.allclose(phi, [0.5, -0.1, 1, 0.5 * math.sqrt(3) - 1 / math.sqrt(3)], atol=1e-14)
    assert np.allclose(n[:, 0], [0, 0, -1]) and np.allclose(n[:, 1], [-1, 0, 0]) and np.allclose(n[:, 2], [0, 0, 1])
    assert np.allclose(n[:, 3], 1 / math.sqrt(3))
    flipped = tri.copy()
    flipped[3] = flipped[3, ::-1]
    for cells, params, words in ((tri[:3], {}, "not closed"), (flipped, {}, "not consistently oriented"),
                                 (flipped, {"side": "normals"}, "not consistently oriented")):
        with pytest.raises(ObstacleError) as e:
            ob.SurfaceMesh(write_msh22(tmp_path / "bad.msh", p, cells), **params)
        assert words in one_line(e)
    # the same tetrahedron as a cavity: the signs flip
    assert np.allclose(ob.SurfaceMesh(tmp_path / "tet.msh", side="inside").distance(pts((0, 0, 2)))[0], [-1])


def test_the_floor_is_exactly_y():
    # the plane foundation y >= 0 as a half-plane: phi is y itself, bit for bit (the normal (0, 5)
    # normalises to exactly (0, 1, 0)), so a run with it can reproduce the bound u_y >= -y exactly
    x = RNG.uniform(-1, 1, (3, 50))
    x[2] = 0
    phi, n = ob.HalfSpace((0, 0), (0, 5)).distance(x)
    assert np.array_equal(phi, x[1]) and np.array_equal(n, np.repeat([[0.0], [1.0], [0.0]], 50, axis=1))


def test_outline_of_a_rotating_cam():
    # a wedge turning about the origin: at the time t its outline passes through the rotated apex
    # and each piece lies on the rotated faces (phi = 0 there)
    w, t = 1.1, 0.9
    o = ob.Wedge((0.5, 0), (1, 1), (-1, 1), rotation=((0, 0), w))
    pieces = o.outline(t, ((-2, -2, 0), (2, 2, 0)))
    allp = np.concatenate(pieces)
    apex = 0.5 * np.array([math.cos(w * t), math.sin(w * t), 0])
    assert any(np.allclose(p, apex) for p in allp)
    assert np.allclose(o.distance(allp.T, t)[0], 0, atol=1e-12) and np.all(np.abs(allp[:, :2]) <= 2 + 1e-15)


def winding_number(x, p, tri):
    """The generalised winding number of the closed triangle surface at the points x (n, 3): 1 inside,
    0 outside (the sum of the triangles' signed solid angles, Van Oosterom & Strackee 1983, over 4 pi)."""
    a, b, c = (p[tri[:, k]][None] - x[:, None] for k in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
    dot = lambda u, v: np.einsum("nmi,nmi->nm", u, v)                     # noqa: E731
    den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb
    return (2 * np.arctan2(dot(a, np.cross(b, c)), den)).sum(axis=1) / (4 * np.pi)


def test_signs_on_a_concave_surface_agree_with_the_winding_number(tmp_path):
    # a cube with a cylindrical hole and a corner cut away (gmsh booleans: concave edges and corners,
    # genus 1): the sign of phi must say inside exactly where the winding number does, for random
    # points and for points 1e-3 off the surface on either side of random triangles
    import gmsh
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        box = gmsh.model.occ.addBox(-1, -1, -1, 2, 2, 2)
        tools = [(3, gmsh.model.occ.addCylinder(0, 0, -2, 0, 0, 4, 0.5)),
                 (3, gmsh.model.occ.addBox(0.2, 0.2, 0.2, 1, 1, 1))]
        gmsh.model.occ.cut([(3, box)], tools)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(tmp_path / "concave.msh"))
    finally:
        gmsh.finalize()
    o = ob.SurfaceMesh(tmp_path / "concave.msh")
    t = RNG.integers(0, len(o.cells), 300)
    on = np.einsum("nk,nki->ni", RNG.dirichlet([1, 1, 1], 300), o.points[o.cells[t]])
    for x in (RNG.uniform(-1.5, 1.5, (2000, 3)), on + 1e-3 * o.normals[t], on - 1e-3 * o.normals[t]):
        inside = winding_number(x, o.points, o.cells) > 0.5
        assert np.array_equal(o.distance(x.T)[0] < 0, inside)


@pytest.mark.parametrize("cls,args", [(ob.Ball, ((0.0, 0.0), 1.0)), (ob.HalfSpace, ((0.0, 0.0), (0.0, 1.0)))])
def test_a_misspelt_parameter_is_refused_in_one_line_naming_the_right_ones(cls, args):
    with pytest.raises(ObstacleError, match=r"unknown parameter\(s\) 'insde'; takes .*motion") as e:
        cls(*args, insde=True)
    assert "\n" not in str(e.value) and "__init__" not in str(e.value)
