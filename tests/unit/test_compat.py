"""compat: the version shims build the spaces, vectors, forms and matrices the package needs.

On the rectangle (0, 2) x (0, 3) cut into nx x ny squares of two triangles: V = (nx+1)(ny+1)
vertices, F = 2 nx ny cells, E = V + F - 1 edges (Euler). P1: V dofs, P2: V + E, P1+bubble:
V + F, DG0: F; a 2-vector: twice as many. The mass of a constant is the area, 6.
"""
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat

COMM = MPI.COMM_WORLD
NX, NY, LX, LY = 3, 2, 2.0, 3.0
VERTS = (NX + 1) * (NY + 1)
CELLS = 2 * NX * NY
EDGES = VERTS + CELLS - 1
AREA = LX * LY
#: sums of O(100) positive terms of size ~ area / 100: round-off ~ 1e-15 relative
SUM_RTOL = 1e-13


@pytest.fixture(scope="module")
def msh():
    return dmesh.create_rectangle(COMM, [np.zeros(2), np.array([LX, LY])], [NX, NY], dmesh.CellType.triangle)


def make(msh, kind, shape=()):
    cell = compat.cell_name(msh)
    if kind == "P1+":
        return compat.function_space(msh, compat.p1_bubble_element(cell, shape))
    family, degree = {"P1": ("Lagrange", 1), "P2": ("Lagrange", 2), "DG0": ("DG", 0)}[kind]
    return compat.function_space(msh, compat.element(family, cell, degree, shape))


DIMS = {"P1": VERTS, "P2": VERTS + EDGES, "P1+": VERTS + CELLS, "DG0": CELLS}
#: dofs per cell: 3 vertices; + 3 edges; + 1 bubble; 1
PER_CELL = {"P1": 3, "P2": 6, "P1+": 4, "DG0": 1}


def test_cell_name(msh):
    assert compat.cell_name(msh) == "triangle"


@pytest.mark.parametrize("kind", sorted(DIMS))
@pytest.mark.parametrize("shape", [(), (2,)])
def test_space_dimensions(msh, kind, shape):
    V = make(msh, kind, shape)
    bs = shape[0] if shape else 1
    im = V.dofmap.index_map
    assert V.dofmap.index_map_bs == bs
    assert im.size_global == DIMS[kind]
    # the cell-to-dof table has one row per local cell, PER_CELL blocks each
    table = compat.dofmap_list(V)
    ncells = msh.topology.index_map(2).size_local + msh.topology.index_map(2).num_ghosts
    assert table.shape == (ncells, PER_CELL[kind])
    # petsc_vec: a vector over the owned dofs (ghosts live only in the Function's array)
    f = fem.Function(V)
    v = compat.petsc_vec(f)
    assert v.getLocalSize() == im.size_local * bs and v.getSize() == DIMS[kind] * bs
    assert f.x.array.size == (im.size_local + im.num_ghosts) * bs


@pytest.mark.parametrize("kind", ["P1", "P2", "P1+"])
def test_mass_of_a_constant_is_the_area(msh, kind):
    V = make(msh, kind)
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    # e, the interpolant of 1, is exactly the constant field in each of these spaces (they
    # contain P1), so e^T M e = (1, 1) = |Omega|
    M = compat.assemble_matrix(compat.form(ufl.inner(u, w) * ufl.dx))
    e = fem.Function(V)
    e.interpolate(lambda x: np.ones(x.shape[1]))
    ev = compat.petsc_vec(e)
    Me = M.createVecLeft()
    M.mult(ev, Me)
    assert abs(ev.dot(Me) - AREA) <= SUM_RTOL * AREA                 # e^T M e = |Omega|
    b = compat.assemble_vector(compat.form(ufl.inner(e, w) * ufl.dx))
    assert abs(b.dot(ev) - AREA) <= SUM_RTOL * AREA                  # (1, e) = |Omega|
    # assemble_vector adds ghost contributions to their owners: (1, phi_i) >= 0 for P1, and
    # the owned entries over all ranks add up to the area (no part lost or counted twice)
    if kind == "P1":
        assert abs(b.sum() - AREA) <= SUM_RTOL * AREA
        assert COMM.allreduce(float(b.array.min(initial=np.inf)), op=MPI.MIN) > 0
    M.destroy()
    b.destroy()


def test_scalar_form_is_the_area(msh):
    local = fem.assemble_scalar(compat.form(fem.Constant(msh, PETSc.ScalarType(1.0)) * ufl.dx(domain=msh)))
    assert abs(COMM.allreduce(local, op=MPI.SUM) - AREA) <= SUM_RTOL * AREA


def test_dg0_mass_is_diagonal_cell_areas(msh):
    V = make(msh, "DG0")
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    M = compat.assemble_matrix(compat.form(u * w * ufl.dx))
    d = M.getDiagonal()
    # uniform mesh: each cell has area |Omega| / F; DG0 functions have disjoint supports
    assert np.allclose(d.array, AREA / CELLS, rtol=1e-14, atol=0)
    ones = M.createVecRight()
    ones.set(1.0)
    rowsum = M.createVecLeft()
    M.mult(ones, rowsum)
    assert np.allclose(rowsum.array, d.array, rtol=1e-14, atol=0)
    for v in (M, d, ones, rowsum):
        v.destroy()


def test_assemble_matrix_block_shape(msh):
    # the (U, V) block system of the consistent variant: rows of W then of H
    W, H = make(msh, "P1+"), make(msh, "P1")
    u, w, v, q = ufl.TrialFunction(W), ufl.TestFunction(W), ufl.TrialFunction(H), ufl.TestFunction(H)
    forms = [[compat.form(ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx), compat.form(v * w * ufl.dx)],
             [compat.form(u * q * ufl.dx), compat.form(-v * q * ufl.dx)]]
    K = compat.assemble_matrix_block(forms)
    n = DIMS["P1+"] + DIMS["P1"]
    assert K.getSize() == (n, n)
    assert K.isSymmetric(tol=1e-13)                   # the off-diagonal blocks are transposes
    K.destroy()


def test_trapezoid():
    x = np.linspace(0.0, 1.0, 11)
    assert abs(compat.trapezoid(x, x) - 0.5) <= 1e-15          # exact for a linear integrand


def test_versions():
    v = compat.versions()
    assert v["dolfinx"] == dolfinx.__version__
    assert v["petsc"] == ".".join(map(str, PETSc.Sys.getVersion()))
    assert compat.DOLFINX_VERSION == tuple(int(p) for p in dolfinx.__version__.split(".")[:2])
    assert all(isinstance(s, str) and s for s in v.values())


@pytest.mark.parametrize("kind,dim,expected", [("P1", 1, 0), ("P2", 1, 1), ("P2", 2, 0), ("P1+", 2, 1), ("P1+", 0, 1),
                                               ("DG0", 2, 1)])
def test_num_entity_dofs(msh, kind, dim, expected):
    """Dofs on one entity's interior: P2 one per edge, the bubble one per cell, per block (a 2-vector alike)."""
    assert compat.num_entity_dofs(make(msh, kind), dim) == expected
    assert compat.num_entity_dofs(make(msh, kind, (2,)), dim) == expected


def test_create_mesh_from_arrays():
    """Two triangles of the unit square (on each rank alone): area 1, 4 vertices."""
    domain = ufl.Mesh(compat.element("Lagrange", "triangle", 1, shape=(2,)))
    x = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    m = compat.create_mesh(MPI.COMM_SELF, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64), x, domain)
    assert m.topology.index_map(0).size_local == 4 and m.topology.index_map(2).size_local == 2
    one = fem.Constant(m, PETSc.ScalarType(1.0))
    assert np.isclose(fem.assemble_scalar(compat.form(one * ufl.dx(domain=m))), 1.0, rtol=SUM_RTOL)


def test_solve_linear_problem(msh):
    """The L2 projection of x + 2y into P1 (which holds it) is x + 2y at the dofs, to round-off of LU."""
    V = make(msh, "P1")
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    x = ufl.SpatialCoordinate(msh)
    uh = compat.solve_linear_problem(ufl.inner(u, w) * ufl.dx, ufl.inner(x[0] + 2 * x[1], w) * ufl.dx, [],
                                     {"ksp_type": "preonly", "pc_type": "lu"}, "sdm_test_projection_")
    X = V.tabulate_dof_coordinates()
    n = V.dofmap.index_map.size_local
    assert np.allclose(uh.x.array[:n], X[:n, 0] + 2 * X[:n, 1], rtol=0, atol=1e-12 * (LX + 2 * LY))
