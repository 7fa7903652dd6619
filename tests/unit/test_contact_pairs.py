"""Contact pairs between bodies: the master surface's geometry and shape functions
(sdm_dolfinx/method/master_surface.py), the rows' structure (body_rows.py), and every combination that is
not built refused in one line (problems/constraint_checks.py, body_rows.refusal)."""
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh as dmesh

from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.method.master_surface import barycentric, facet_normals
from sdm_dolfinx.problems import Body, ContactPair, ProblemInputError, load_file
from sdm_dolfinx.run import simulate

COMM = MPI.COMM_WORLD
DEMOS = Path(__file__).resolve().parents[2] / "demos"
RNG = np.random.default_rng(7)


def _bars(**values):
    return load_file(DEMOS / "two_bars_problem.py").problem(COMM, **{"Nx": 4, "Ny": 2, **values})


def _one_line(e):
    text = str(e.value)
    assert "\n" not in text
    return text


# ------------------------------------------------------------------ shape functions and geometry
def test_barycentric_and_normals():
    corners = np.array([[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.0]]])
    xi = RNG.dirichlet(np.ones(3), size=20)
    pts = xi @ corners[0] + np.array([0.0, 0.0, 0.7])             # off the plane: projected
    np.testing.assert_allclose(barycentric(pts, np.repeat(corners, 20, axis=0)), xi, atol=1e-14)
    np.testing.assert_allclose(facet_normals(corners), [[0.0, 0.0, 1.0]], atol=1e-15)
    seg = np.array([[[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])               # (t_y, -t_x): +x
    np.testing.assert_allclose(facet_normals(seg), [[1.0, 0.0, 0.0]], atol=1e-15)


@pytest.mark.mpi
@pytest.mark.parametrize("pair", ["P2/P1", "P1+/P0", "P1/P0"])
def test_the_master_face_of_the_two_bars(pair):
    """Bar 2's end face x = d: outward normal -e_x on every facet and at every vertex, the rows read its
    vertices' dofs (P2's midpoints not: master_surface.py), and a point at x projects on it at its signed
    distance d - x, with the weights of the nearest points' vertices."""
    p = _bars()
    d = Discretisation(p, pair)
    s = d.body_rows.surfaces[0]
    assert s.cells.shape == (2, 2) and len(s.points) == 3                  # Ny = 2 facets, on every rank
    assert len(s.dofs) == 3 * 2                                            # 3 vertices, 2 components
    np.testing.assert_allclose(facet_normals(s.points[s.cells]), np.tile([-1.0, 0.0, 0.0], (2, 1)), atol=1e-15)
    np.testing.assert_allclose(s.vertex_normals, np.tile([-1.0, 0.0, 0.0], (3, 1)), atol=1e-15)
    gap = p.parameters["gap"] / 2.0
    y = np.array([[-0.3, 2.5, 0.0], [gap + 0.1, 7.5, 0.0]])
    phi, n, el, xi = s.project(y, np.zeros(len(s.dofs)))
    np.testing.assert_allclose(phi, [gap + 0.3, -0.1], atol=1e-12)
    np.testing.assert_allclose(np.sort(xi, axis=1), [[0.5, 0.5], [0.5, 0.5]], atol=1e-12)   # facet midpoints


@pytest.mark.mpi
def test_the_rows_push_the_bodies_equally_and_oppositely():
    """Each row's coefficients sum to zero per component (sum_a N_a = 1): G^T lam has no resultant, so
    the contact conserves the total momentum. Checked on a state that has moved and sheared the master."""
    d = Discretisation(_bars(Ny=3), "P2/P1")
    rows = d.body_rows
    u = RNG.standard_normal(d.W.dofmap.index_map.size_local * 2) * 1e-3
    (ids, vals), g = rows.rows(u, 0.0, 1e-6, 0.5)
    assert len(g) == len(rows.dofs) and COMM.allreduce(len(g), op=MPI.SUM) == 4   # the slave face's vertices
    for comp in (0, 1):
        np.testing.assert_allclose(np.sum(np.where(ids % 2 == comp, vals, 0.0), axis=1), 0.0, atol=1e-14)
    assert np.all(np.abs(vals[:, 0] + 1.0) < 1e-6)                          # n = -e_x (bar 2's face) on the slave


@pytest.mark.mpi
def test_the_tangential_rows_are_the_normal_rows_along_the_tangent():
    """Friction between bodies: each slave vertex's tangential row has the normal row's weights along
    t = (n_y, -n_x): its slave part is a unit vector orthogonal to n, its master part -xi_v t, so it too has
    no resultant (equal and opposite friction forces). Same moved and sheared state as above."""
    d = Discretisation(_bars(Ny=3), "P2/P1")
    rows = d.body_rows
    u = RNG.standard_normal(d.W.dofmap.index_map.size_local * 2) * 1e-3
    (ids0, normal), g0 = rows.rows(u, 0.0, 1e-6, 0.5)
    (ids, vals), g = rows.rows(u, 0.0, 1e-6, 0.5, tangential=True)
    np.testing.assert_array_equal(ids, ids0)
    np.testing.assert_array_equal(g, g0)
    np.testing.assert_array_equal(vals[0], normal)
    n, t = vals[0][:, :2], vals[1][:, :2]
    np.testing.assert_allclose(np.einsum("ij,ij->i", n, t), 0.0, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(t, np.column_stack([n[:, 1], -n[:, 0]]), atol=0.0)
    for comp in (0, 1):
        np.testing.assert_allclose(np.sum(np.where(ids % 2 == comp, vals[1], 0.0), axis=1), 0.0, atol=1e-14)
    # the master part: -xi_v t, with the normal row's xi_v (normal master entry = -xi_v n_c)
    master = ids[:, 2:] % 2
    xi_n = np.where(master == 0, normal[:, 2:] / n[:, :1], normal[:, 2:] / n[:, 1:])
    ok = np.abs(np.where(master == 0, n[:, :1], n[:, 1:])) > 0.5
    expect = -xi_n * np.where(master == 0, t[:, :1], t[:, 1:])
    np.testing.assert_allclose(np.where(ok, vals[1][:, 2:], 0.0), np.where(ok, expect, 0.0), atol=1e-14)


# ------------------------------------------------------------------ refusals, one line each
@pytest.mark.parametrize("change, words", [
    (dict(lower_bound=lambda x: x[0]), "set lower_bound to None"),
    (dict(constraint_vertices=lambda m: np.zeros(0, dtype=np.int32)), "set constraint_vertices to None"),
    (dict(contact_pairs=["ends"]), "must hold ContactPair objects, not str"),
    (dict(contact_pairs="ends"), "must be a list of ContactPair"),
    (dict(contact_pairs=[ContactPair(None, None, name="a b")]), "distinct words"),
    (dict(contact_pairs=[], lower_bound=lambda x: x[0]), "constraint_vertices is None and there are no contact_pairs"),
    (dict(contact_pairs=[]), "lower_bound is None and there are no obstacles or contact_pairs"),
])
def test_bad_declarations_are_refused(change, words):
    p = _bars()
    for k, v in change.items():
        setattr(p, k, v)
    with pytest.raises(ProblemInputError) as e:
        p.validate()
        Discretisation(p, "P2/P1")
    assert words in _one_line(e)


@pytest.mark.parametrize("kw, words", [
    (dict(contact="penalty"), "which contact 'penalty' does not take yet"),
    (dict(scheme="newmark"), "which scheme 'newmark' does not take"),
    (dict(mass="consistent", pair="P2/P1"), "mass 'consistent'"),
    (dict(constrain="nodes"), "constrain 'nodes' does not take yet"),
    (dict(vi_solver="vinewtonrsls"), "semi-smooth Newton with linear strategy schur only"),
])
def test_what_is_not_built_is_refused_in_one_line(kw, words, mpi_tmp_path):
    kw = {"pair": "P2/P1", "dt": 5e-7, "T": 2e-6, **kw}
    with pytest.raises(Exception) as e:
        simulate(_bars(), out=mpi_tmp_path / "r", **kw)
    assert words in _one_line(e)


def test_the_equilibrium_start_is_refused(mpi_tmp_path):
    p = _bars()
    p.u0 = "equilibrium"
    with pytest.raises(DiscretisationError) as e:
        simulate(p, pair="P2/P1", dt=5e-7, T=2e-6, out=mpi_tmp_path / "r")
    assert "equilibrium start is not built for contact pairs" in _one_line(e)


def test_a_master_that_names_interior_facets_is_refused():
    p = _bars()
    msh = p.mesh
    interior = lambda m: np.arange(m.topology.index_map(1).size_local, dtype=np.int32)     # noqa: E731
    p.contact_pairs = [ContactPair(slave=p.contact_pairs[0].slave, master=interior)]
    with pytest.raises(DiscretisationError) as e:
        Discretisation(p, "P2/P1")
    assert "interior facets" in _one_line(e) and msh is p.mesh


def test_an_initial_overlap_is_refused():
    p = _bars()
    gap = p.parameters["gap"]
    p.u0 = lambda x: np.vstack([np.where(x[0] < 0, 2.0 * gap, 0.0), 0.0 * x[1]])
    with pytest.raises(DiscretisationError) as e:
        Discretisation(p, "P2/P1").initial_state()
    assert "inside a master body" in _one_line(e)


@pytest.mark.mpi
@pytest.mark.parametrize("pair, well_posed", [("P2/P1", True), ("P1+/P0", True), ("P1/P1", False), ("P2/P2", False)])
def test_inspect_measures_condition_7_on_the_rows_between_bodies(pair, well_posed):
    """The inspector's beta of condition (7) is taken on the two-body rows (slave and master columns): the
    paper's classes (the well-posed pairs carry every row by a massless W; the standard pairs have none)."""
    from sdm_dolfinx.analysis.infsup import gap_matrix, inspect
    G = gap_matrix(Discretisation(_bars(), pair))          # on rank 0
    if COMM.rank == 0:      # at U = 0 each slave vertex faces its mirror vertex: n = -e_x, -1 there, +1 at the slave
        assert G.shape[0] == 3 and np.all(np.diff(G.indptr) == 2)
        np.testing.assert_allclose(np.sort(G.toarray(), axis=1)[:, [0, -1]], np.tile([-1.0, 1.0], (3, 1)), atol=1e-14)
    r = inspect(_bars(), pair)
    assert (r["beta"] > 1e-3) == well_posed and r["verdict"] == ("well-posed" if well_posed else "ill-posed")


@pytest.mark.mpi
@pytest.mark.parametrize("which", ["discs", "balls"])
def test_the_facets_near_a_ranks_points_project_as_the_whole_surface(which):
    """MasterSurface.nearby sends a rank the deformed master facets near its own points only; the
    projection on them is the projection on the whole surface (every rank holding it: displacements), for
    points near the surface and far from it (several sizes off: the search's other branch), in a rough
    deformed state, with a rank without points (discs on 2 ranks) or with (balls). A second projection of
    the same points takes one round; a point at a vertex gets fewer facets than the surface's."""
    if which == "discs":
        p = load_file(DEMOS / "two_discs_problem.py").problem(COMM, level=1)
    else:
        from sdm_dolfinx.problems import two_balls
        p = two_balls.problem(COMM, level=1)
    d = Discretisation(p, "P2/P1")
    s, gdim = d.body_rows.surfaces[0], p.shape[0]
    rng = np.random.default_rng(11 + COMM.rank)
    owned = d.W.dofmap.index_map.size_local * d.W.dofmap.index_map_bs
    u = 2e-3 * s.size * rng.standard_normal(owned)
    h = np.median(np.linalg.norm(s.points[s.cells[:, 1]] - s.points[s.cells[:, 0]], axis=1))
    count = 0 if (which == "discs" and COMM.rank == 1) else 25
    base = s.points[rng.integers(len(s.points), size=count)]
    noise = np.zeros((count, 3))
    noise[:, :gdim] = rng.standard_normal((count, gdim))
    near = base + 0.3 * h * noise
    far = base + np.linspace(2.0, 8.0, count)[:, None] * h * noise / np.maximum(
        np.linalg.norm(noise, axis=1, keepdims=True), 1e-300)
    whole = s.displacements(u)
    for y in (near, np.vstack([near, far])):
        phi, n, el, xi = s.project(y, whole)
        vals, facets, cand = s.nearby(u, y)
        got = s.project(y, vals, facets, cand)
        np.testing.assert_allclose(got[0], phi, rtol=0.0, atol=1e-12 * s.size)
        np.testing.assert_allclose(got[1], n, rtol=0.0, atol=1e-12)
        # the same closest points (a point at a vertex or an edge may name either of its facets)
        cur = s.points[s.cells] + np.pad(whole[s.at], ((0, 0), (0, 0), (0, 3 - gdim)))
        np.testing.assert_allclose(np.einsum("pv,pvk->pk", got[3], cur[got[2]]),
                                   np.einsum("pv,pvk->pk", xi, cur[el]), rtol=0.0, atol=1e-12 * s.size)
        s.nearby(u, y)
        assert s.rounds == 1
    one = s.points[:1] if count else np.zeros((0, 3))          # a point at a vertex: a few facets sent
    s.reach = 0.0                                              # (not the far points' reach)
    s.nearby(u, one)
    s.nearby(u, one)                                           # from the reach the first one found
    assert s.rounds == 1 and ((0 < s.received < len(s.cells)) if count else s.received == 0)


@pytest.mark.mpi
def test_inspect_measures_two_passes_on_their_distinct_rows():
    """Two passes on matching faces: every second-pass row repeats a first-pass one (the same unit vector),
    so G P_F G^T is singular; the constraint set is the one pass's, and the inspector measures it on the
    distinct rows: the one-pass beta exactly, the repeated rows counted. A row and its negative are two
    bounds, not a repeat."""
    from sdm_dolfinx.analysis.infsup import inspect
    from sdm_dolfinx.analysis.repeated_rows import distinct_rows
    one, two = inspect(_bars(), "P2/P1"), inspect(_bars(passes=2), "P2/P1")
    assert two["repeated_rows"] == 3 and two["N_g"] == one["N_g"] == 3 and one["repeated_rows"] == 0
    assert two["beta"] == pytest.approx(one["beta"], rel=1e-10) and two["verdict"] == "well-posed"
    assert "3 more repeat" in two["reason"]
    import scipy.sparse as sp
    G = sp.csr_matrix(np.array([[1.0, -1.0, 0.0], [2.0, -2.0, 0.0], [-1.0, 1.0, 0.0], [1.0, -1.0, 1e-3]]))
    np.testing.assert_array_equal(distinct_rows(G), [0, 2, 3])


def test_a_point_beyond_the_rim_of_the_master_has_no_row():
    """The master face of the bars ends at y = 0 and y = H: a point above its top corner, off to the side by
    more than the rim tolerance, is beyond the surface (no normal: its row holds nothing, its gap is its
    distance to the corner), while a point just above the face's middle is held along -e_x."""
    p = _bars()
    s = Discretisation(p, "P2/P1").body_rows.surfaces[0]
    gap, H = p.parameters["gap"] / 2.0, p.parameters["H"]
    y = np.array([[gap - 0.5, H + 2.0, 0.0], [gap - 0.5, H / 2.0, 0.0]])
    phi, n, _, _ = s.project(y, np.zeros(len(s.dofs)))
    np.testing.assert_allclose(n[0], 0.0) and np.testing.assert_allclose(phi[0], np.hypot(0.5, 2.0), rtol=1e-12)
    np.testing.assert_allclose(n[1], [-1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(phi[1], 0.5, rtol=1e-12)


@pytest.mark.parametrize("slave, words", [
    (lambda m: np.array([-1], dtype=np.int32), "slave returned facet indices outside"),
    (lambda m: np.arange(m.topology.index_map(1).size_local, dtype=np.int32), "interior facets"),
    (lambda m: np.zeros(0, dtype=np.int32), "slave names no exterior facet on any rank"),    # else: no contact
])
def test_bad_slave_facets_are_refused(slave, words):
    p = _bars()
    p.contact_pairs = [ContactPair(slave=slave, master=p.contact_pairs[0].master)]
    with pytest.raises(DiscretisationError) as e:
        Discretisation(p, "P2/P1")
    assert words in _one_line(e)


@pytest.mark.mpi
def test_facets_and_cells_chosen_by_where_they_are():
    """sdm_dolfinx.problems.facets_where / cells_where on the touching case: two bars of Nx x Ny squares
    meeting at x = 0 (gap_time 0): the facets on x = 0 are each bar's end face (Ny facets each, told apart by
    their cells' side), and each bar has 2 Nx Ny triangles."""
    from sdm_dolfinx.problems import cells_where, facets_where
    p = _bars(gap_time=0.0, Nx=4, Ny=3)
    msh = p.mesh
    at_zero = lambda x: np.isclose(x[0], 0.0)                                  # noqa: E731
    count = lambda f: COMM.allreduce(int(np.count_nonzero(                     # noqa: E731
        f < msh.topology.index_map(1).size_local)), op=MPI.SUM)
    left, right, both = (facets_where(at_zero, side=lambda c: c[0] < 0)(msh),
                         facets_where(at_zero, side=lambda c: c[0] > 0)(msh), facets_where(at_zero)(msh))
    assert count(left) == count(right) == 3 and count(both) == 6 and not np.intersect1d(left, right).size
    cells = cells_where(lambda c: c[0] < 0)(msh)
    owned = msh.topology.index_map(2).size_local
    assert COMM.allreduce(int(np.count_nonzero(cells < owned)), op=MPI.SUM) == 2 * 4 * 3


def test_a_constraint_measure_off_the_slave_facets_is_refused():
    """The bars' measure on bar 2's end face (the master) instead of bar 1's (the slave): the slave vertices'
    stresses would divide by 0."""
    import ufl
    p = _bars()
    master = np.sort(p.contact_pairs[0].master(p.mesh)).astype(np.int32)
    tags = dmesh.meshtags(p.mesh, 1, master, np.ones_like(master))
    p.constraint_measure = lambda q: q * ufl.Measure("ds", domain=p.mesh, subdomain_data=tags)(1)
    with pytest.raises(DiscretisationError) as e:
        Discretisation(p, "P2/P1")
    assert "constraint_measure gives 3 slave vertices no measure" in _one_line(e)


def test_a_body_that_is_its_own_master_is_refused():
    p = _bars()
    p.contact_pairs = [ContactPair(slave=p.contact_pairs[0].slave, master=p.contact_pairs[0].slave)]
    with pytest.raises(DiscretisationError) as e:
        Discretisation(p, "P2/P1")
    assert "slave vertices are on its master surface too" in _one_line(e)


def test_bodies_touching_in_the_reference_mesh_cannot_restart(mpi_tmp_path):
    """A checkpoint names dofs by their positions: two bodies sharing node positions make a restart
    ambiguous, which is refused in one line (a silent mix-up of the bodies' states before)."""
    from sdm_dolfinx.io.checkpoint import CheckpointError
    kw = dict(pair="P1+/P0", dt=5e-7, T=5e-6)
    simulate(_bars(gap_time=0.0), out=mpi_tmp_path / "r", **kw)
    with pytest.raises(Exception) as e:
        simulate(_bars(gap_time=0.0), out=mpi_tmp_path / "r", restart=True, **{**kw, "T": 1e-5})
    assert isinstance(e.value, CheckpointError) or "cannot be restarted" in str(e.value)
    assert "share" in _one_line(e) and "cannot be restarted" in _one_line(e)


@pytest.mark.parametrize("bodies, words", [
    ("striker", "bodies must be a list of Body"),
    (["striker"], "bodies must hold Body objects, not str"),
    ([Body("a b", lambda m: np.zeros(0, dtype=np.int32))], "distinct words"),
])
def test_bad_bodies_are_refused(bodies, words):
    p = _bars()
    p.bodies = bodies
    with pytest.raises(ProblemInputError) as e:
        p.validate()
    assert words in _one_line(e)


def test_bodies_that_share_dofs_are_refused(mpi_tmp_path):
    p = _bars()
    every = lambda m: np.arange(m.topology.index_map(2).size_local, dtype=np.int32)      # noqa: E731
    p.bodies = [Body("one", every), Body("two", every)]
    with pytest.raises(DiscretisationError) as e:
        simulate(p, pair="P2/P1", dt=5e-7, T=1e-6, out=mpi_tmp_path / "r")
    assert "share" in _one_line(e)


def _slider_on_two_bases(comm):
    """A slider [20, 40] x [1, 11] (10 x 5 squares) 1 mm above two bases side by side, A = [0, 30] x [-10, 0]
    and B = [30.5, 60] x [-10, 0] (clamped below), gravity: the slider's bottom vertices are the slave of
    two pairs, one per base."""
    import ufl
    from petsc4py import PETSc
    from dolfinx import fem
    from sdm_dolfinx import compat
    from sdm_dolfinx.compat.mesh import create_mesh, mesh_geometry_dofmap
    from sdm_dolfinx.problems import Problem

    def rect(x0, x1, n):
        m = dmesh.create_rectangle(MPI.COMM_SELF, [np.array(x0), np.array(x1)], n, dmesh.CellType.triangle)
        return m.geometry.x[:, :2].copy(), np.asarray(mesh_geometry_dofmap(m), dtype=np.int64)
    if comm.rank == 0:
        parts = [rect([20.0, 1.0], [40.0, 11.0], [10, 5]), rect([0.0, -10.0], [30.0, 0.0], [15, 4]),
                 rect([30.5, -10.0], [60.0, 0.0], [15, 4])]
        x = np.vstack([p[0] for p in parts])
        shift = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
        cells = np.vstack([p[1] + s for p, s in zip(parts, shift)])
    else:
        x, cells = np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    msh = create_mesh(comm, cells, x, ufl.Mesh(compat.element("Lagrange", "triangle", 1, (2,))))

    def cells_where(test):
        def found(m):
            c = np.arange(m.topology.index_map(2).size_local + m.topology.index_map(2).num_ghosts, dtype=np.int32)
            mid = dmesh.compute_midpoints(m, 2, c)
            return c[test(mid[:, 0], mid[:, 1])]
        return found

    def face(y0, x0, x1):
        return lambda m: dmesh.locate_entities_boundary(
            m, 1, lambda p: np.isclose(p[1], y0) & (p[0] >= x0 - 1e-9) & (p[0] <= x1 + 1e-9))
    slave = np.sort(face(1.0, 20.0, 40.0)(msh)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, 1, slave, np.ones_like(slave)))(1)
    eps = lambda u: ufl.sym(ufl.grad(u))                                      # noqa: E731
    weight = fem.Constant(msh, PETSc.ScalarType((0.0, -1e-6 * 9810.0)))
    return Problem(
        name="two_bases", mesh=msh, shape=(2,), rho=1e-6,
        a=lambda u, w: 1000.0 * ufl.inner(eps(u), eps(w)) * ufl.dx, l=lambda w: ufl.inner(weight, w) * ufl.dx,
        u0=lambda p: np.zeros((2, p.shape[1])), v0=lambda p: np.zeros((2, p.shape[1])),
        dirichlet_facets=lambda m: dmesh.locate_entities_boundary(m, 1, lambda p: np.isclose(p[1], -10.0)),
        dirichlet_value=lambda p: np.zeros((2, p.shape[1])),
        constraint_vertices=None, lower_bound=None,
        contact_pairs=[ContactPair(slave=face(1.0, 20.0, 40.0), master=face(0.0, 0.0, 30.0), name="A"),
                       ContactPair(slave=face(1.0, 20.0, 40.0), master=face(0.0, 30.5, 60.0), name="B")],
        bodies=[Body("slider", cells_where(lambda x, y: y > 0.5))],
        constraint_component=1, constraint_measure=lambda q: q * ds_c, probe=(30.0, 1.0),
        extra_columns=("contact_force",))


@pytest.mark.mpi
def test_a_slave_vertex_in_two_pairs_is_held_by_the_nearer_master(mpi_tmp_path):
    """Every slave vertex of the slider belongs to both pairs; its row is against the nearer base (A up to x
    = 30, B from x = 32 on: x = 30 is 1 mm from A's corner and 1.118 mm from B's), at the gap 1 mm. Dropped
    by gravity on both: each pair carries part of it, the pairs' columns add up to the run's, and the
    slider's momentum balance closes on them: p_y(t) - p_y(0) = sum of the contact impulses - m g t."""
    p = _slider_on_two_bases(COMM)
    d = Discretisation(p, "P2/P1")
    rows = d.body_rows
    u = np.zeros(d.W.dofmap.index_map.size_local * 2)
    _, g = rows.rows(u, 0.0, 1e-4, 0.5)
    x = rows.x[0]
    assert COMM.allreduce(len(x), op=MPI.SUM) == 11
    np.testing.assert_array_equal(rows.pair_of_row, np.where(x <= 30.0, 0, 1))
    np.testing.assert_allclose(rows.phi(u), 1.0, atol=1e-12)
    dt = 1e-4
    ts = simulate(p, pair="P2/P1", dt=dt, T=0.02, out=mpi_tmp_path / "r").timeseries
    fa, fb = ts["contact_force_A"], ts["contact_force_B"]
    assert fa.max() > 0.0 and fb.max() > 0.0
    np.testing.assert_allclose(fa + fb, ts["contact_force"], rtol=1e-13, atol=0.0)
    m = 1e-6 * 20.0 * 10.0
    py = ts["momentum_slider_y"]
    np.testing.assert_allclose(py - py[0], np.cumsum(ts["contact_force"]) * dt - m * 9810.0 * ts["t"],
                               rtol=0.0, atol=1e-9 * m * 9810.0 * ts["t"][-1])
