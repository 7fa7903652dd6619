"""The modified masses of the standard pairs (method/masses.py), against facts that do not
depend on the code:

* the moments e_a^T M e_b (a, b in {1, x, y}, e_a the nodal interpolant of a: exact in P1 and
  P2) of the consistent mass are rho times the polynomial moments of the domain, in closed form
  (rectangle (0, lx) x (0, ly), interval (0, 1)); the redistributed mass keeps all of them (total
  mass, centre of mass, second moments) to 1e-12;
* the row-sum mass keeps the total mass and the centre of mass (1^T diag(M 1) x = 1^T M x), and its
  second moments are the nodal (vertex) quadrature's: on a simplex of dimension d, for affine f, g,
  sum_i |T|/(d+1) f_i g_i - (f, g) = |T| / ((d+1)(d+2)) sum_{i<j} (f_i - f_j)(g_i - g_j) (from
  (phi_i, phi_j) = |T| (1 + delta_ij) / ((d+1)(d+2))); P2 on an interval gives Simpson's weights,
  exact for the cubic integrands x^2: all moments kept;
* the redistributed mass is symmetric, positive semi-definite, and its rows and columns vanish
  exactly at the constrained nodes (every component) and only there; its kernel is theirs;
* on the 1-D P1 rod the construction has a closed form: the contact node moves with 2 v_1 - v_2;
* 1 and 2 ranks give the same quadratic forms.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import scipy.sparse
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.mpiutil import gather_rows
from sdm_dolfinx.problems import Problem, block, membrane

COMM = MPI.COMM_WORLD
RTOL = 1e-12
RHO = 2.5
#: the block of these tests: (0, 20) x (0, 10) mm, 8 x 4 squares (h = 2.5 mm), density 1e-6
LX, LY, NX, NY, RHO_BLOCK = 20.0, 10.0, 8, 4, 1e-6


def rod(n=6, comm=COMM, rho=RHO, stretch=False):
    """A hand-made 1-D Problem on (0, 1): the wave equation, u(1) = 0, u(0) >= 0 (contact at x = 0),
    ``n`` cells, uniform or (``stretch``) graded by x -> (x + x^2) / 2 (cells from h/2 to 3h/2)."""
    msh = dmesh.create_interval(comm, n, [0.0, 1.0])
    if stretch:
        x = msh.geometry.x[:, 0]
        msh.geometry.x[:, 0] = 0.5 * (x + x * x)
    at0 = lambda x: np.isclose(x[0], 0.0)                                    # noqa: E731
    facets = np.sort(dmesh.locate_entities_boundary(msh, 0, at0)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, 0, facets, np.ones_like(facets)))(1)
    zero = fem.Constant(msh, PETSc.ScalarType(0.0))
    return Problem(
        name="rod", mesh=msh, shape=(), rho=rho,
        a=lambda u, w: ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx, l=lambda w: zero * w * ufl.dx,
        u0=lambda x: 0.5 - 0.5 * x[0], v0=lambda x: np.zeros(x.shape[1]),
        constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, at0),
        lower_bound=lambda x: np.zeros(x.shape[1]), constraint_measure=lambda q: q * ds_c,
        dirichlet_facets=lambda m: dmesh.locate_entities_boundary(m, 0, lambda x: np.isclose(x[0], 1.0)),
        dirichlet_value=lambda x: np.zeros(x.shape[1]))


def the_block(comm=COMM):
    """The block problem (vector, contact at its bottom y = 0), unstressed start (no static solve)."""
    return block.problem(comm, width=LX, height=LY, nx=NX, ny=NY, rho=RHO_BLOCK, start="rest")


def monomials(gdim):
    """1, x, (y): the affine monomials whose moments are checked."""
    return [lambda x: np.ones(x.shape[1])] + [lambda x, k=k: x[k] for k in range(gdim)]


def moments(d):
    """Q[(a, c), (b, c')] = e_a^T M e_b for the affine monomials a, b in each component c (collective)."""
    shape = d.problem.shape
    ncomp = shape[0] if shape else 1
    vecs = []
    for c in range(ncomp):
        for f in monomials(d.problem.mesh.geometry.dim):
            g = fem.Function(d.W)
            if shape:
                g.interpolate(lambda x, f=f, c=c: np.vstack([f(x) if k == c else 0.0 * x[0] for k in range(ncomp)]))
            else:
                g.interpolate(f)
            vecs.append(compat.petsc_vec(g).copy())
    Q = np.zeros((len(vecs), len(vecs)))
    y = vecs[0].duplicate()
    for j, b in enumerate(vecs):
        d.mass_mult(b, y)
        for i, a in enumerate(vecs):
            Q[i, j] = a.dot(y)
    return Q


def exact_moments(rho, box):
    """rho times the moments of 1, x, (y) over the interval (0, lx) or the rectangle (0, lx) x (0, ly)."""
    if len(box) == 1:
        (lx,) = box
        m = np.array([[lx, lx ** 2 / 2], [lx ** 2 / 2, lx ** 3 / 3]])
    else:
        lx, ly = box
        area = lx * ly
        mx, my = lx ** 2 / 2 * ly, ly ** 2 / 2 * lx
        m = np.array([[area, mx, my], [mx, lx ** 3 / 3 * ly, lx ** 2 / 2 * ly ** 2 / 2],
                      [my, lx ** 2 / 2 * ly ** 2 / 2, ly ** 3 / 3 * lx]])
    return rho * m


def block_moments(rho, box, ncomp):
    """exact_moments for each component (the mass couples no two components)."""
    return np.kron(np.eye(ncomp), exact_moments(rho, box))


def nodal_quadrature_excess(msh, rho):
    """sum over cells of rho |T|/((d+1)(d+2)) sum_{i<j} (f_i - f_j)(g_i - g_j) for f, g in {1, x, (y)}:
    the P1 row-sum mass's moments minus the exact ones (module docstring), reduced over ranks."""
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    msh.topology.create_connectivity(tdim, 0)
    ncells = msh.topology.index_map(tdim).size_local
    from sdm_dolfinx import compat
    nodes = compat.mesh_geometry_dofmap(msh)[:ncells, :tdim + 1]
    X = msh.geometry.x[nodes][:, :, :gdim]                     # (cells, d+1, gdim)
    E = X[:, 1:, :] - X[:, :1, :]
    vol = np.abs(np.linalg.det(E)) / {1: 1, 2: 2, 3: 6}[tdim]       # tdim == gdim here
    F = np.concatenate([np.ones(X.shape[:2] + (1,)), X], axis=2)  # values of 1, x, y at the vertices
    out = np.zeros((gdim + 1, gdim + 1))
    for i in range(tdim + 1):
        for j in range(i + 1, tdim + 1):
            dF = F[:, i, :] - F[:, j, :]
            out += np.einsum("c,ca,cb->ab", vol / ((tdim + 1) * (tdim + 2)), dF, dF)
    return rho * msh.comm.allreduce(out, op=MPI.SUM)


def dense(A, comm=COMM):
    """The global dense matrix of a distributed PETSc AIJ matrix on rank 0 (None elsewhere)."""
    indptr, indices, data = A.getValuesCSR()
    r0, r1 = A.getOwnershipRange()
    local = scipy.sparse.csr_matrix((data, indices, indptr), shape=(r1 - r0, A.getSize()[1])).toarray()
    return gather_rows(local, comm)


def global_constrained(d):
    """The global W dofs of every component of every constrained node, on rank 0 (None elsewhere)."""
    bs = d.W.dofmap.index_map_bs
    off = d.W.dofmap.index_map.local_range[0]
    blocks = np.unique(d.cdofs // bs) + off
    allb = gather_rows(blocks, d.comm)
    if d.comm.rank != 0:
        return None
    return np.sort((allb[:, None] * bs + np.arange(bs)[None, :]).reshape(-1))


# ------------------------------------------------------------------------------ moments
CASES_2D = [("P1/P1", "vertices"), ("P2/P2", "vertices"), ("P2/P2", "nodes")]


@pytest.mark.parametrize("pair, constrain", CASES_2D)
def test_redistributed_keeps_mass_centre_and_inertia_2d(pair, constrain):
    d = Discretisation(the_block(), pair, "redistributed", constrain=constrain)
    exact = block_moments(RHO_BLOCK, (LX, LY), 2)
    Q, Q0 = moments(d), moments(Discretisation(the_block(), pair, "standard"))
    assert np.abs(Q0 - exact).max() <= RTOL * np.abs(exact).max()      # the consistent M: the closed form
    assert np.abs(Q - exact).max() <= RTOL * np.abs(exact).max()


@pytest.mark.parametrize("pair", ["P1/P1", "P2/P2"])
@pytest.mark.parametrize("stretch", [False, True])
def test_redistributed_keeps_mass_centre_and_inertia_1d(pair, stretch):
    d = Discretisation(rod(stretch=stretch), pair, "redistributed")
    exact = exact_moments(RHO, (1.0,))
    assert np.abs(moments(d) - exact).max() <= RTOL * np.abs(exact).max()


@pytest.mark.parametrize("problem", ["block", "rod"])
def test_row_sum_keeps_mass_and_centre_and_second_moments_are_the_nodal_rule(problem):
    p = the_block() if problem == "block" else rod(stretch=True)
    rho, box = (RHO_BLOCK, (LX, LY)) if problem == "block" else (RHO, (1.0,))
    d = Discretisation(p, "P1/P1", "row-sum")
    Q = moments(d)[:len(box) + 1, :len(box) + 1]                   # component 0 (the others are equal)
    exact = exact_moments(rho, box)
    scale = np.abs(exact).max()
    assert np.abs(Q[0] - exact[0]).max() <= RTOL * scale           # total mass and centre of mass
    excess = nodal_quadrature_excess(p.mesh, rho)
    assert excess[1, 1] > 1e-3 * scale                               # the vertex rule is not exact for x^2
    assert np.abs(Q - (exact + excess)).max() <= RTOL * scale       # second moments: the vertex rule


def test_row_sum_p2_on_an_interval_is_simpson():
    # P2 row sums on an interval are h/6, 2h/3 (Simpson), exact for the integrands 1, x, x^2
    d = Discretisation(rod(stretch=True), "P2/P2", "row-sum")
    exact = exact_moments(RHO, (1.0,))
    assert np.abs(moments(d) - exact).max() <= RTOL * np.abs(exact).max()


def test_row_sum_p2_on_triangles_is_refused_in_one_line():
    with pytest.raises(DiscretisationError) as e:
        Discretisation(the_block(), "P2/P2", "row-sum")
    msg = str(e.value)
    assert "\n" not in msg and "row-sum" in msg and "triangle" in msg and "redistributed" in msg


# ------------------------------------------------------------------------------ the matrix itself
@pytest.mark.parametrize("problem, pair, constrain",
                         [("block", p, c) for p, c in CASES_2D] + [("rod", "P1/P1", "vertices"),
                                                                   ("rod", "P2/P2", "vertices")])
def test_redistributed_is_psd_and_singular_exactly_at_the_constrained_nodes(problem, pair, constrain):
    p = the_block() if problem == "block" else rod()
    d = Discretisation(p, pair, "redistributed", constrain=constrain)
    M, zero = dense(d.M), global_constrained(d)
    if COMM.rank == 0:
        scale = np.abs(M).max()
        assert np.abs(M - M.T).max() <= 1e-15 * scale
        ev = np.linalg.eigvalsh(M)
        assert ev.min() >= -1e-12 * ev.max()
        # rows and columns exactly zero at every component of the constrained nodes, and only there
        rows = np.flatnonzero(np.all(M == 0.0, axis=1))
        assert np.array_equal(rows, zero) and np.array_equal(np.flatnonzero(np.all(M == 0.0, axis=0)), zero)
        assert np.all(np.diag(M)[np.setdiff1d(np.arange(len(M)), zero)] > 0.0)
        # the kernel is theirs: as many (numerically) zero eigenvalues as zero rows
        assert int(np.sum(ev <= 1e-12 * ev.max())) == len(zero) > 0


def test_rod_p1_closed_form():
    """P1, uniform h: the contact node 0's donors are nodes 1 and 2 (two rings; its first ring holds
    node 1 only) and the affine weights are (2, -1): M_r = P^T M P with (P v)_0 = 2 v_1 - v_2, whose
    entries follow by hand from M = rho h/6 [[2, 1], [1, 2]] per cell."""
    n = 6
    h = 1.0 / n
    d = Discretisation(rod(n=n), "P1/P1", "redistributed")
    M, x = dense(d.M), gather_rows(d.W.tabulate_dof_coordinates()[:d.W.dofmap.index_map.size_local, 0], COMM)
    if COMM.rank == 0:
        o = np.argsort(x)
        M = M[np.ix_(o, o)] / (RHO * h)
        expected = np.array([[0, 0, 0, 0], [0, 8 / 3, -2 / 3, 0], [0, -2 / 3, 1, 1 / 6], [0, 0, 1 / 6, 2 / 3]])
        assert np.abs(M[:4, :4] - expected).max() <= 1e-13


def test_no_donor_is_refused_in_one_line():
    # the membrane's obstacle constrains every interior vertex: in P1 no free node carries their mass
    with pytest.raises(DiscretisationError) as e:
        Discretisation(membrane.problem(COMM, N=4), "P1/P1", "redistributed")
    assert "\n" not in str(e.value) and "redistributed" in str(e.value) and "P2/P2" in str(e.value)


def test_without_constraint_redistributed_is_the_consistent_mass():
    d = Discretisation(membrane.problem(COMM, N=3, with_obstacle=False), "P1/P1", "redistributed")
    d0 = Discretisation(membrane.problem(COMM, N=3, with_obstacle=False), "P1/P1")
    M, M0 = dense(d.M), dense(d0.M)
    if COMM.rank == 0:
        assert np.abs(M - M0).max() <= 1e-15 * np.abs(M0).max()


# ------------------------------------------------------------------------------ ranks
@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="compares a distributed mass with a serial one: needs mpirun -n 2")
@pytest.mark.parametrize("pair, mass, constrain", [("P1/P1", "redistributed", "vertices"),
                                                   ("P2/P2", "redistributed", "nodes"),
                                                   ("P1/P1", "row-sum", "vertices")])
def test_one_and_two_ranks_give_the_same_quadratic_forms(pair, mass, constrain):
    par = moments(Discretisation(the_block(COMM), pair, mass, constrain=constrain))
    ser = moments(Discretisation(the_block(MPI.COMM_SELF), pair, mass, constrain=constrain)) \
        if COMM.rank == 0 else None
    ser = COMM.bcast(ser, root=0)
    assert np.abs(par - ser).max() <= RTOL * np.abs(ser).max()
    # and a form the moments do not fix: the kinetic energy of a non-affine field
    def kinetic(comm):
        d = Discretisation(the_block(comm), pair, mass, constrain=constrain)
        g = fem.Function(d.W)
        g.interpolate(lambda x: np.vstack([np.sin(x[0] / 3) * x[1], np.cos(x[1] / 2) + x[0] ** 2]))
        v, y = compat.petsc_vec(g).copy(), compat.petsc_vec(g).copy()
        d.mass_mult(v, y)
        return v.dot(y)
    par = kinetic(COMM)
    ser = COMM.bcast(kinetic(MPI.COMM_SELF) if COMM.rank == 0 else None, root=0)
    assert abs(par - ser) <= RTOL * abs(ser)
