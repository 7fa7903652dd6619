"""Discretisation (method/discretisation.py) on tiny meshes, against facts of the paper's
section 2 that do not depend on the code:

* M = B^T C^-1 B is symmetric positive semi-definite (C is SPD, or its positive lumped
  diagonal), and Ker M = Ker B, so dim Ker M = dim W - dim H when B has full row rank;
* the constant field e is in W^h and in H^h, so B e = C 1 (and also = C_lumped 1, the row
  sums): e^T M e = e^T B^T 1 = rho |Omega|, the total mass, for every pair and treatment;
* the constrained dofs (eq. (13)) are vertex dofs, with the problem's bound evaluated at
  those vertices; Dirichlet dofs are fixed and leave the constraint set.

Dense checks gather the matrices to rank 0 (tiny: dim W <= 49). 1 and 2 ranks.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import scipy.sparse
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.pairs import PAIRS
from sdm_dolfinx.mpiutil import gather_rows
from sdm_dolfinx.problems import Problem, membrane

COMM = MPI.COMM_WORLD
#: e^T M e sums O(dim W) products of O(1) numbers: round-off ~ 1e-15 relative; the
#: consistent variant applies C^-1 by CG to rtol 1e-14 (Discretisation.solve_C)
MASS_RTOL = 1e-12

#: every (pair, mass treatment) the registry allows
TREATMENTS = [(name, mass) for name, pair in PAIRS.items() for mass in pair.allowed_masses()
              if (name, mass) not in (("P2/P2", "row-sum"), ("P1/P1", "redistributed"))]
#: those that form M
FORMED = [(name, mass) for name, mass in TREATMENTS if mass != "consistent"]


def toy_problem(n=3, shape=(2,), rho=2.5, lx=2.0, ly=1.0, constrain="interior", dirichlet=True, bound=None):
    """A problem built by hand on the rectangle (0, lx) x (0, ly) (area lx ly): vector or
    scalar Laplacian, density ``rho``; constrained vertices 'interior', 'all' or 'none',
    component 1 bounded below by ``bound(x)``; u = (0.1, 0.2) (or 0.1) on the boundary."""
    msh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([lx, ly])], [2 * n, n],
                                 dmesh.CellType.triangle)
    tdim = msh.topology.dim

    def on_boundary(x):
        return np.isclose(x[0], 0) | np.isclose(x[0], lx) | np.isclose(x[1], 0) | np.isclose(x[1], ly)

    def vertices(m):
        nv = m.topology.index_map(0).size_local + m.topology.index_map(0).num_ghosts
        everything = np.arange(nv, dtype=np.int32)
        if constrain == "all":
            return everything
        if constrain == "none":
            return np.zeros(0, dtype=np.int32)
        return np.setdiff1d(everything, dmesh.locate_entities_boundary(m, 0, on_boundary)).astype(np.int32)

    def facets(m):
        m.topology.create_connectivity(tdim - 1, tdim)
        return dmesh.exterior_facet_indices(m.topology)

    gval = (0.1, 0.2)[:shape[0]] if shape else (0.1,)
    f = fem.Constant(msh, PETSc.ScalarType(-1.0)) if not shape else fem.Constant(msh, np.array((0.0, -1.0)))
    return Problem(
        name="toy", mesh=msh, shape=shape, rho=rho,
        a=lambda u, w: ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx,
        l=lambda w: ufl.inner(f, w) * ufl.dx,
        u0=lambda x: np.zeros((shape[0], x.shape[1])) if shape else np.zeros(x.shape[1]),
        v0=lambda x: np.zeros((shape[0], x.shape[1])) if shape else np.zeros(x.shape[1]),
        constraint_vertices=vertices,
        lower_bound=bound or (lambda x: -x[1] + 0.3 * x[0]),
        constraint_component=1 if shape else None,
        constraint_measure=lambda q: q * ufl.dx,
        dirichlet_facets=facets if dirichlet else None,
        dirichlet_value=(lambda x: np.vstack([np.full(x.shape[1], g) for g in gval])) if shape
        else (lambda x: np.full(x.shape[1], gval[0])),
    )


def dense(A):
    """The global dense array of a distributed PETSc AIJ matrix, on rank 0 (None elsewhere)."""
    indptr, indices, data = A.getValuesCSR()
    r0, r1 = A.getOwnershipRange()
    local = scipy.sparse.csr_matrix((data, indices, indptr), shape=(r1 - r0, A.getSize()[1])).toarray()
    return gather_rows(local, COMM)


def on_rank0(func, *args):
    """Evaluate ``func`` on rank 0 (dense linear algebra) and give its result to every rank."""
    return COMM.bcast(func(*args) if COMM.rank == 0 else None, root=0)


def mass_form(d, x, y):
    """x^T M y through Discretisation.mass_mult (M formed or not)."""
    my = y.duplicate()
    d.mass_mult(y, my)
    return x.dot(my)


# ------------------------------------------------------------------------------ total mass
@pytest.mark.parametrize("name, mass", TREATMENTS)
def test_constant_field_carries_the_total_mass_scalar(name, mass):
    # membrane: rho = 1 on the unit square: e^T M e = 1
    d = Discretisation(membrane.problem(COMM, N=3), name, mass)
    e = d.rigid_vector(0)
    assert abs(mass_form(d, e, e) - 1.0) <= MASS_RTOL
    if d.M is not None:
        Me = d.M.createVecLeft()
        d.M.mult(e, Me)
        assert abs(e.dot(Me) - 1.0) <= MASS_RTOL


@pytest.mark.parametrize("name, mass", TREATMENTS)
def test_constant_field_carries_the_total_mass_vector(name, mass):
    # rho = 2.5 on (0, 2) x (0, 1): each component carries rho |Omega| = 5; the mass form
    # rho u.w couples no two components, so e_x^T M e_y = 0
    rho, area = 2.5, 2.0
    d = Discretisation(toy_problem(rho=rho), name, mass)
    ex, ey = d.rigid_vector(0), d.rigid_vector(1)
    assert abs(mass_form(d, ex, ex) - rho * area) <= MASS_RTOL * rho * area
    assert abs(mass_form(d, ey, ey) - rho * area) <= MASS_RTOL * rho * area
    assert abs(mass_form(d, ex, ey)) <= MASS_RTOL * rho * area


@pytest.mark.parametrize("name, mass", [(n, m) for n, m in FORMED if m in ("diagonal", "lumped")])
def test_lumped_C_is_positive_and_sums_to_the_mass(name, mass):
    rho, area = 2.5, 2.0
    d = Discretisation(toy_problem(rho=rho), name, mass)
    c = d.c_lumped
    # the diagonal of C: (psi_i, 1) rho, a positive share of the mass for P0 and P1
    assert COMM.allreduce(float(np.min(c.array, initial=np.inf)), op=MPI.MIN) > 0.0
    # each component's diagonal sums to rho |Omega| (the mass carried by that component)
    for k in (0, 1):
        total = COMM.allreduce(float(c.array[k::2].sum()), op=MPI.SUM)
        assert abs(total - rho * area) <= MASS_RTOL * rho * area
    if mass == "diagonal":
        # P0: C is exactly diagonal, C_KK = rho |K| = rho lx ly / (2 * 2n * n) on the uniform mesh
        Cd = dense(d.C)
        off = on_rank0(lambda C: float(np.abs(C - np.diag(np.diag(C))).max()), Cd)
        assert off == 0.0
        cell = rho * area / (2 * 6 * 3)
        assert COMM.allreduce(float(np.max(np.abs(c.array - cell), initial=0.0)), op=MPI.MAX) <= 1e-14 * cell


# ------------------------------------------------------------------------------ M itself
@pytest.mark.parametrize("name, mass", FORMED)
def test_M_symmetric_semidefinite_with_the_kernel_of_B(name, mass):
    d = Discretisation(membrane.problem(COMM, N=3), name, mass)
    dims = d.dims()
    M = dense(d.M)
    B = dense(d.B) if d.B is not None else None

    def analyse(M, B):
        scale = np.abs(M).max()
        ev = np.linalg.eigvalsh(0.5 * (M + M.T))
        # eigenvalues below 1e-10 of the largest are round-off (kernel ones ~1e-16 of the
        # largest; the smallest others >= 2e-2 of it on this mesh, checked by 'gap' below)
        kernel = int(np.sum(ev < 1e-10 * ev.max()))
        rank_B = int(np.linalg.matrix_rank(B)) if B is not None else None
        return {"asym": float(np.abs(M - M.T).max() / scale), "min": float(ev.min() / ev.max()),
                "kernel": kernel, "rank_B": rank_B, "shape": M.shape,
                "gap": float(ev[ev >= 1e-10 * ev.max()].min() / ev.max())}
    r = on_rank0(analyse, M, B)
    nW, nH = dims["dim_W"], dims["dim_H"]
    assert r["shape"] == (nW, nW)
    assert r["asym"] <= 1e-15                     # B^T D^-1 B is symmetric by construction
    assert r["min"] >= -1e-14                     # and positive semi-definite
    assert r["gap"] > 1e-6                        # a clear gap between kernel and the rest
    if d.B is None:
        # standard Galerkin: the SPD mass matrix, or (redistributed) no inertia at the constrained nodes
        assert r["kernel"] == (d.num_constraints if mass == "redistributed" else 0)
    else:
        # C is SPD (or a positive diagonal): Ker M = Ker B, of dimension dim W - rank B
        assert r["kernel"] == nW - r["rank_B"]
        if name == "P1+/P0":
            # full row rank: each cell's P0 function meets that cell's own bubble, which no
            # other P0 function sees, so dim Ker M = dim W - dim H (Lemma 2's counting)
            assert r["rank_B"] == nH and r["kernel"] == nW - nH
        elif name == "P1/P0":
            # the paper's counterexample: dim H (2 N^2) > dim W ((N+1)^2) here, so B cannot have
            # full row rank; Ker B holds at least the two three-colour modes (next test)
            assert r["kernel"] >= 2
        else:
            # H = P1 is in W (P1 or P2 or P1+): B restricted to H x H is C, SPD: full row rank
            assert r["rank_B"] == nH and r["kernel"] == nW - nH


def test_P1_P0_kernel_holds_the_three_colour_modes():
    """P1/P0: colour vertex (i, j) of the 'right' mesh (diagonals from (i, j) to (i+1, j+1)) by
    (i + j) mod 3; every triangle has one vertex of each colour, so a P1 field taking values
    c_0, c_1, c_2 on the colours with c_0 + c_1 + c_2 = 0 has zero mean on every cell: B v = 0,
    hence M v = 0 -- two displacement modes without kinetic energy, whatever N."""
    N = 4
    d = Discretisation(membrane.problem(COMM, N=N), "P1/P0")
    x = d.W.tabulate_dof_coordinates()[:d.W.dofmap.index_map.size_local]
    colour = np.rint(x[:, 0] * N + x[:, 1] * N).astype(int) % 3
    Mv = d.M.createVecLeft()
    for c in ((1.0, -1.0, 0.0), (0.0, 1.0, -1.0)):
        v = d.M.createVecRight()
        v.array[:] = np.array(c)[colour]
        d.M.mult(v, Mv)
        # relative to ||M|| ||v||: M's entries are O(1/N^2), so round-off is ~1e-16 of that
        assert Mv.norm(PETSc.NormType.NORM_INFINITY) <= 1e-14 * d.M.norm(PETSc.NormType.NORM_INFINITY)
        assert v.norm() > 1.0
        v.destroy()
    # the colouring matters: a field that is not colour-wise constant is seen by M
    v = d.M.createVecRight()
    v.array[:] = x[:, 0]
    d.M.mult(v, Mv)
    assert Mv.norm(PETSc.NormType.NORM_INFINITY) > 1e-3 * d.M.norm(PETSc.NormType.NORM_INFINITY)


def test_M_is_B_transpose_Dinv_B():
    # the definition of M (paper eq. (5)) with D = diag(row sums of C), checked densely
    d = Discretisation(toy_problem(n=1, rho=2.5), "P2/P1")
    M, B, c = dense(d.M), dense(d.B), gather_rows(np.array(d.c_lumped.array), COMM)
    err = on_rank0(lambda M, B, c: float(np.abs(M - B.T @ (B / c[:, None])).max() / np.abs(M).max()), M, B, c)
    assert err <= 1e-14


def test_mass_treatment_not_allowed_for_the_pair():
    with pytest.raises(ValueError) as e:
        Discretisation(membrane.problem(COMM, N=2), "P1+/P0", "lumped")
    assert "diagonal" in str(e.value) and "P1+/P0" in str(e.value)


# ------------------------------------------------------------------------------ constraints
def grid(n_x, n_y, lx, ly, interior=True):
    """The sorted vertex coordinates of the structured rectangle mesh (closed form)."""
    i0 = 1 if interior else 0
    pts = [(lx * i / n_x, ly * j / n_y) for i in range(i0, n_x + 1 - i0) for j in range(i0, n_y + 1 - i0)]
    return np.array(sorted(pts))


@pytest.mark.parametrize("name", ["P1+/P0", "P2/P1", "P1/P1", "P2/P2"])
def test_membrane_constrained_dofs_are_interior_vertices(name):
    N, obstacle = 4, -0.05
    d = Discretisation(membrane.problem(COMM, N=N, obstacle=obstacle), name)
    assert d.num_constraints == (N - 1) ** 2 == d.dims()["N_g"]
    # owned dofs, one per constrained vertex, located at that vertex (a vertex dof)
    assert np.all(d.cdofs < d.W.dofmap.index_map.size_local)
    xd = d.W.tabulate_dof_coordinates()[d.cdofs]
    assert np.allclose(xd, d.cx.T, rtol=0, atol=1e-14)
    assert np.all(d.lb == obstacle)
    pts = gather_rows(d.cx[:2].T, COMM)
    ok = on_rank0(lambda p: p.shape == ((N - 1) ** 2, 2) and np.allclose(
        np.array(sorted(map(tuple, p))), grid(N, N, 1.0, 1.0), atol=1e-14), pts)
    assert ok                                     # every interior vertex exactly once


def test_membrane_without_obstacle_has_no_constraint():
    d = Discretisation(membrane.problem(COMM, N=3, with_obstacle=False), "P1+/P0")
    assert d.num_constraints == 0 and d.cdofs.size == 0 and d.lb.size == 0


@pytest.mark.parametrize("name", ["P1+/P0", "P2/P1"])
def test_vector_bound_on_its_component_at_its_vertex(name):
    # component 1 bounded by g(x) = -y + 0.3 x: the bound read at the vertex of each dof
    d = Discretisation(toy_problem(n=2, constrain="interior"), name)
    bs = d.W.dofmap.index_map_bs
    assert bs == 2 and np.all(d.cdofs % bs == 1)
    x = d.W.tabulate_dof_coordinates()[d.cdofs // bs]
    assert np.allclose(d.lb, -x[:, 1] + 0.3 * x[:, 0], rtol=0, atol=1e-14)
    # the vertices are mesh grid points (i lx / 2n, j ly / n), never edge midpoints
    ij = x[:, :2] / np.array([2.0 / 4, 1.0 / 2])
    assert np.allclose(ij, np.round(ij), atol=1e-12)
    assert d.num_constraints == (2 * 2 - 1) * (2 - 1)


@pytest.mark.parametrize("name, shape, on_boundary", [
    ("P1/P1", (), lambda V, E: V), ("P1+/P0", (), lambda V, E: V), ("P2/P1", (), lambda V, E: V + E),
    ("P2/P1", (2,), lambda V, E: 2 * (V + E)), ("P1+/P0", (2,), lambda V, E: 2 * V)])
def test_dirichlet_dofs_leave_the_constraint_set(name, shape, on_boundary):
    n = 2
    prob = toy_problem(n=n, shape=shape, constrain="all")
    d = Discretisation(prob, name)
    # boundary of the 2n x n rectangle: 2 (2n + n) vertices and as many edges; the bubbles
    # vanish there; P2 has a dof at each boundary edge's midpoint
    nb = 2 * (2 * n + n)
    assert COMM.allreduce(d.ddofs.size, op=MPI.SUM) == on_boundary(nb, nb)
    assert np.intersect1d(d.cdofs, d.ddofs).size == 0
    # all vertices were declared; the (2n - 1)(n - 1) interior ones remain constrained
    assert d.num_constraints == (2 * n - 1) * (n - 1)
    assert len(d.lb) == len(d.cdofs) == d.cx.shape[1] == len(d.cmeasure)
    # the Dirichlet values are the problem's at those dofs, and U0 starts from them
    g = np.array([0.1, 0.2])[d.ddofs % 2] if shape else np.full(d.ddofs.size, 0.1)
    assert np.array_equal(d.g.x.array[d.ddofs], g)
    U0, V0 = d.initial_state()
    assert np.array_equal(U0.array[d.ddofs], g) and np.all(V0.array[d.ddofs] == 0.0)


def test_constraint_measure_sums_to_the_area():
    # constraint_measure = q dx: the lumped P1 measures of all vertices sum to |Omega| = 2
    d = Discretisation(toy_problem(n=2, constrain="all", dirichlet=False), "P1+/P0")
    assert d.num_constraints == 5 * 3
    assert abs(COMM.allreduce(float(d.cmeasure.sum()), op=MPI.SUM) - 2.0) <= 1e-14
