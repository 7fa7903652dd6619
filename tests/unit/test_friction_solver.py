"""The frictional step solver on hand-made problems: the KKT conditions of Signorini contact
with Tresca or Coulomb friction, closed forms, an independent enumeration of the contact
states, the frictionless solver at mu = 0, and 1 against 2 ranks.

With r = K x - b the obstacle's reaction, lam_N = r_n, lam_T = r_t, d = x_t - xref and
g = s (Tresca) or mu lam_N (Coulomb), a solution satisfies

    x_n >= lb, lam_N >= 0, lam_N (x_n - lb) = 0,  |lam_T| <= g,
    |lam_T| < g => d = 0,   d != 0 => lam_T = -g sign(d),   r = 0 off the contact dofs.

Problems: one block on a plane (K diagonal: closed forms); a chain of blocks joined by
oblique springs (t and n coupled, so the Coulomb Newton systems are non-symmetric), whose
every contact state is enumerated with numpy as the reference; a plane-strain elastic block
(dolfinx, K = alpha^2 M + A) pressed on a shallow bowl and dragged sideways. The tests
marked ``mpi`` run distributed under ``mpirun -n 2`` (whole vertices on each rank).
"""
import itertools

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import scipy.sparse
import ufl
from dolfinx import mesh

from sdm_dolfinx import compat
from sdm_dolfinx.solvers import SemismoothNewton, VIError, friction_system
from sdm_dolfinx.solvers import friction_newton as friction
from sdm_dolfinx.solvers.friction_newton import FrictionalNewton

COMM = MPI.COMM_WORLD
#: the solver stops at violations of 1e-10 max|b| (its rtol); the Newton systems are solved
#: to round-off (cond(K) <= 1e4 here), so 1e-9 leaves a margin
RTOL = 1e-9
#: the Coulomb methods (``auto``: Newton, then the fixed point if Newton fails)
COULOMB = ("newton", "fixed-point", "auto")


# ------------------------------------------------------------------------------ problems
def vertex_rows(nv, comm=COMM):
    """This rank's vertices [lo, hi) of nv (both dofs of a vertex on one rank)."""
    sizes = [nv // comm.size + (r < nv % comm.size) for r in range(comm.size)]
    lo = sum(sizes[:comm.rank])
    return lo, lo + sizes[comm.rank]


def chain_matrix(m, eps=0.05, k=1.0):
    """Blocks i = 0..m-1 with dofs (t_i, n_i) = (2i, 2i+1): block 0 tied to a wall by a
    tangential spring, neighbours by springs at 30 degrees (coupling t and n) and isotropic
    ones, plus a small mass term eps I (the step matrix's alpha^2 M). SPD."""
    e = np.array([np.cos(np.pi / 6), np.sin(np.pi / 6)])
    K = eps * np.eye(2 * m)
    K[0, 0] += 2.0 * k
    for i in range(m - 1):
        B = np.zeros((2, 2 * m))
        B[:, 2 * i:2 * i + 2], B[:, 2 * i + 2:2 * i + 4] = np.eye(2), -np.eye(2)
        K += k * B.T @ np.outer(e, e) @ B + 0.2 * k * B.T @ B
    return K


class Blocks:
    """The PETSc data of a problem on blocks (dofs (t_i, n_i) = (2i, 2i+1), global dense
    ``Kg``), distributed over the ranks by whole blocks; loads F sideways, -P down."""

    def __init__(self, Kg, F, P, lb=None, comm=COMM):
        self.Kg, self.m = Kg, len(F)
        self.lbg = np.zeros(self.m) if lb is None else np.asarray(lb, dtype=float)
        self.lo, self.hi = lo, hi = vertex_rows(self.m, comm)
        sub = scipy.sparse.csr_matrix(Kg[2 * lo:2 * hi])
        csr = (sub.indptr.astype(PETSc.IntType), sub.indices.astype(PETSc.IntType), sub.data)
        n = 2 * (hi - lo)
        self.K = PETSc.Mat().createAIJ(((n, 2 * self.m), (n, 2 * self.m)), csr=csr, comm=comm)
        self.K.assemble()
        self.b, self.x = self.K.createVecLeft(), self.K.createVecRight()
        self.tdofs = np.arange(0, n, 2, dtype=np.int32)
        self.ndofs = self.tdofs + 1
        self.lb = self.lbg[lo:hi]
        self.load(F, P)

    def load(self, F, P):
        self.bg = np.ravel(np.column_stack([F, -np.asarray(P)]))
        self.b.array[:] = self.bg[2 * self.lo:2 * self.hi]

    def gather(self, v):
        return np.concatenate(COMM.allgather(np.asarray(v)))

    def destroy(self):
        for o in (self.K, self.b, self.x):
            o.destroy()


#: the meshes and spaces of the assembled matrices, kept alive with them: on dolfinx 0.9 a matrix
#: whose mesh was garbage-collected crashes in createVecLeft (its local-to-global map is freed)
_ALIVE = []


def elastic_block(nx=12, ny=6, p=0.05, a2=0.01, comm=COMM):
    """Plane-strain block [0, 2] x [0, 1] (E = 1, nu = 0.3, P1): K = a2 I_mass + A, the top
    pressed down by p (load ``b``) and dragged sideways (load ``drag`` per unit traction);
    the bottom vertices are the contact ones, over the obstacle x_n >= -0.05 (x - 1)^2 (a
    shallow bowl: the ends lift off).

    Returns (K, b, drag, ndofs, tdofs, lb, coordinates of the owned dofs' vertices)."""
    msh = mesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([2.0, 1.0])], [nx, ny])
    V = compat.function_space(msh, compat.element("Lagrange", compat.cell_name(msh), 1, (2,)))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    lmbda, mu = 0.3 / (1.3 * 0.4), 1.0 / 2.6

    def sigma(w):
        eps = ufl.sym(ufl.grad(w))
        return 2.0 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(2)
    a = ufl.inner(sigma(u), ufl.sym(ufl.grad(v))) * ufl.dx + a2 * ufl.inner(u, v) * ufl.dx
    top = ufl.conditional(ufl.gt(ufl.SpatialCoordinate(msh)[1], 1.0 - 1e-8), 1.0, 0.0)
    K = compat.assemble_matrix(compat.form(a))
    _ALIVE.append((msh, V))
    b, drag = (compat.assemble_vector(compat.form(top * f * ufl.ds)) for f in (-p * v[1], v[0]))
    X = V.tabulate_dof_coordinates()[:V.dofmap.index_map.size_local, :2]
    bottom = np.flatnonzero(np.abs(X[:, 1]) < 1e-12)
    lb = -0.05 * (X[bottom, 0] - 1.0) ** 2
    return K, b, drag, (2 * bottom + 1).astype(np.int32), (2 * bottom).astype(np.int32), lb, X


# ------------------------------------------------------------------------------ checks
def assert_kkt(Kg, bg, x, ndofs, tdofs, lb, xref, g_of, rtol=RTOL):
    """The conditions of the module docstring on global arrays; forces relative to max|b|,
    displacements to max|b| / max diag K. ``g_of(lam_N)``: the friction bound."""
    fs = np.max(np.abs(bg))
    xs = fs / np.max(np.diag(Kg)) if isinstance(Kg, np.ndarray) else fs / Kg.diagonal().max()
    r = Kg @ x - bg
    off = np.setdiff1d(np.arange(len(bg)), np.concatenate([ndofs, tdofs]))
    assert np.max(np.abs(r[off]), initial=0.0) <= rtol * fs, "equilibrium off the contact dofs"
    lamN, lamT, gap, d = r[ndofs], r[tdofs], x[ndofs] - lb, x[tdofs] - xref
    g = g_of(lamN)
    assert np.min(gap) >= -rtol * xs and np.min(lamN) >= -rtol * fs
    assert np.max(np.abs(np.minimum(lamN / fs, gap / xs))) <= rtol, "complementarity"
    assert np.all(np.abs(lamT) <= g + rtol * fs), "|lam_T| > g"
    stick = np.abs(lamT) < g - rtol * fs
    assert np.all(np.abs(d[stick]) <= rtol * xs), "inside the friction cone but slipping"
    slip = np.abs(d) > rtol * xs
    assert np.all(np.abs(lamT[slip] + g[slip] * np.sign(d[slip])) <= rtol * fs), "friction not against the slip"
    return lamN, lamT


def enumerate_solutions(Kg, bg, lb, xref, law, coef, rtol=RTOL):
    """Every solution of the chain's frictional problem, by trying every contact state of
    every block (normal: contact or not; tangential: stick, slip +, slip -; Coulomb: no
    friction out of contact) and keeping the linear solutions that meet the conditions."""
    m, n = len(lb), len(bg)
    states = [(c, t) for c in (True, False) for t in ("stick", 1.0, -1.0)
              if c or law == "tresca" or t == "stick"]
    found = []
    for combo in itertools.product(states, repeat=m):
        A = np.zeros((n + 2 * m, n + 2 * m))
        rhs = np.zeros(n + 2 * m)
        A[:n, :n], rhs[:n] = Kg, bg
        A[:n, n:] = -np.eye(n)                 # K x - r = b, r the reactions (2m = n here)
        for i, (contact, t) in enumerate(combo):
            row = n + 2 * i
            if contact:
                A[row, 2 * i + 1], rhs[row] = 1.0, lb[i]          # x_n = lb
            else:
                A[row, n + 2 * i + 1] = 1.0                       # lam_N = 0
            if t == "stick" and (contact or law == "tresca"):
                A[row + 1, 2 * i], rhs[row + 1] = 1.0, xref[i]    # x_t = xref
            elif t == "stick":
                A[row + 1, n + 2 * i] = 1.0                       # no friction off contact
            else:                                                 # lam_T = -t g
                A[row + 1, n + 2 * i] = 1.0
                if law == "tresca":
                    rhs[row + 1] = -t * coef
                else:
                    A[row + 1, n + 2 * i + 1] = t * coef
        try:
            sol = np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError:
            continue
        x = sol[:n]
        try:
            assert_kkt(Kg, bg, x, np.arange(1, n, 2), np.arange(0, n, 2), lb, xref,
                       (lambda lam: np.full(m, coef)) if law == "tresca" else (lambda lam: coef * lam), rtol)
        except AssertionError:
            continue
        if not any(np.max(np.abs(x - y)) <= 1e-8 * max(np.max(np.abs(x)), 1.0) for y in found):
            found.append(x)
    return found


def bound(law, coef):
    return (lambda lam: np.full(len(lam), coef)) if law == "tresca" else (lambda lam: coef * lam)


class Arrays:
    """The fields :func:`make` reads, for a problem given as arrays."""

    def __init__(self, K, ndofs, tdofs, lb):
        self.K, self.ndofs, self.tdofs, self.lb = K, ndofs, tdofs, lb


def make(p, law, coef, method="newton", **kw):
    """The solver of ``law`` with coefficient ``coef`` for problem ``p`` (:class:`Blocks`, :class:`Arrays`)."""
    if law == "tresca":
        return FrictionalNewton(p.K, p.ndofs, p.tdofs, p.lb, law="tresca", threshold=coef, **kw)
    return FrictionalNewton(p.K, p.ndofs, p.tdofs, p.lb, law="coulomb", mu=coef, coulomb=method, **kw)


# ------------------------------------------------------------------------------ tests
@pytest.mark.parametrize("law,method", [("tresca", None)] + [("coulomb", c) for c in COULOMB])
@pytest.mark.parametrize("F", [0.5, -0.9, 1.0, 1.5, -3.0])
def test_single_block_closed_form(law, method, F):
    """One block (kt = 2, kn = 3) pressed by P = 5 onto the plane, pushed sideways by
    F mu P (mu = 0.4; Tresca: s = mu P): it sticks (x_t = 0, lam_T = -F) when |F| <= mu P,
    else it slides with lam_T = -mu P sign(F), x_t = (F - mu P sign F) / kt; lam_N = P."""
    kt, kn, P, mu = 2.0, 3.0, 5.0, 0.4
    Fx = F * mu * P
    p = Blocks(np.diag([kt, kn]), [Fx], [P])
    s = make(p, law, mu * P if law == "tresca" else mu, method)
    info = s.solve(p.b, p.x, np.zeros(len(p.tdofs)))
    x, lam_t = p.gather(p.x.array), p.gather(s.lam_t)
    slides = abs(F) > 1.0
    xt = (Fx - mu * P * np.sign(Fx)) / kt if slides else 0.0
    assert abs(x[0] - xt) <= 1e-14 * P and x[1] == 0.0
    assert np.allclose(p.gather(s.lam), P, rtol=1e-14)
    assert abs(lam_t[0] - (-mu * P * np.sign(Fx) if slides else -Fx)) <= 1e-14 * P
    if abs(F) != 1.0:                          # on the cone's edge both sets are right
        assert (info["n_stick"], info["n_slip"], info["n_active"]) == ((0, 1, 1) if slides else (1, 0, 1))
    s.destroy()
    p.destroy()


@pytest.mark.parametrize("law,coef", [("tresca", 1e9), ("tresca", 0.7), ("coulomb", 0.0)])
def test_single_block_lifted(law, coef):
    """A block pulled up (P = -5) leaves the plane (x_n = 5 / kn, lam_N = 0). Coulomb: no
    friction, x_t = F / kt. Tresca acts at every contact vertex, in contact or not (the
    classical Tresca problem): a huge threshold holds it (x_t = xref), a small one lets it
    slide against s."""
    p = Blocks(np.eye(2), [1.0], [-5.0])
    s = make(p, law, coef)
    xref = np.full(len(p.tdofs), 0.25)
    s.solve(p.b, p.x, xref)
    x = p.gather(p.x.array)
    assert abs(x[1] - 5.0) <= 1e-14 and np.all(p.gather(s.lam) == 0.0)
    expected = {1e9: 0.25, 0.7: 1.0 - 0.7, 0.0: 1.0}[coef]
    assert abs(x[0] - expected) <= 1e-14
    s.destroy()
    p.destroy()


CHAIN_LOADS = [([0.5, 0.1, -0.2], [1.0, 0.5, 1.5]),      # some stick, some slip
               ([0.8, 0.6, 0.4], [1.0, -0.3, 0.4]),      # the middle block pulled up
               ([-0.2, 0.05, 0.3], [0.2, 0.2, 2.0])]


@pytest.mark.mpi
@pytest.mark.parametrize("loads", range(len(CHAIN_LOADS)))
@pytest.mark.parametrize("law,coef,method", [("tresca", 0.1, None), ("tresca", 0.3, None)]
                         + [("coulomb", mu, c) for mu in (0.2, 0.5) for c in COULOMB])
def test_chain_against_enumeration(loads, law, coef, method):
    """The chain of three blocks: the solver meets the KKT conditions and finds the unique
    solution that trying every contact state finds (two steps: the second from the first's
    slip, xref = its x_t, under a reversed sideways load)."""
    F, P = CHAIN_LOADS[loads]
    p = Blocks(chain_matrix(3), F, P, lb=[0.0, -0.1, 0.05])
    s = make(p, law, coef, method)
    xref = np.zeros(p.m)
    for step in range(2):
        s.solve(p.b, p.x, xref[p.lo:p.hi])
        x = p.gather(p.x.array)
        assert_kkt(p.Kg, p.bg, x, np.arange(1, 2 * p.m, 2), np.arange(0, 2 * p.m, 2), p.lbg, xref, bound(law, coef))
        ref = enumerate_solutions(p.Kg, p.bg, p.lbg, xref, law, coef)
        assert len(ref) == 1
        assert np.max(np.abs(x - ref[0])) <= RTOL * np.max(np.abs(ref[0]))
        r = (p.Kg @ x - p.bg)
        assert np.max(np.abs(p.gather(s.lam) - r[1::2])) <= RTOL * np.max(np.abs(p.bg))
        assert np.max(np.abs(p.gather(s.lam_t) - r[0::2])) <= RTOL * np.max(np.abs(p.bg))
        xref = x[0::2].copy()
        p.load(-0.5 * np.asarray(F), P)        # pressed as before, pushed back by half
    s.destroy()
    p.destroy()


@pytest.fixture(scope="module")
def block():
    """The elastic block pressed and dragged by q = 0.01 (contact, stick and slip)."""
    K, b, drag, ndofs, tdofs, lb, X = elastic_block()
    b.axpy(0.01, drag)
    yield K, b, ndofs, tdofs, lb, X, drag
    for o in (K, b, drag):
        o.destroy()


def global_kkt(K, b, x, ndofs, tdofs, lb, xref, g_of):
    """:func:`assert_kkt` on the gathered data of a distributed problem; returns the
    gathered (lam_N, lam_T)."""
    ai, aj, av = K.getValuesCSR()
    A = scipy.sparse.csr_matrix((av, aj, ai), shape=(K.getLocalSize()[0], K.getSize()[1]))
    Kg = scipy.sparse.vstack(COMM.allgather(A)).tocsr()
    off = K.getOwnershipRange()[0]
    g = lambda v: np.concatenate(COMM.allgather(np.asarray(v)))   # noqa: E731
    return assert_kkt(Kg, g(b.array), g(x.array), g(ndofs + off), g(tdofs + off), g(lb), g(xref), g_of)


@pytest.mark.mpi
@pytest.mark.parametrize("law,coef,method,q", [("tresca", 1e-3, None, 0.005), ("tresca", 2e-3, None, 0.01)]
                         + [("coulomb", mu, c, 0.01) for mu in (0.2, 0.5, 1.0) for c in COULOMB])
def test_elastic_block_kkt(block, law, coef, method, q):
    """The elastic block dragged by q, two steps (the second dragged back by q / 2, from the
    first's slip): the KKT conditions hold, with contact, stick and slip all present."""
    K, b, ndofs, tdofs, lb, _, drag = block
    s = make(Arrays(K, ndofs, tdofs, lb), law, coef, method)
    x, b2 = K.createVecRight(), b.copy()
    b2.axpy(q - 0.01, drag)
    xref = np.zeros(len(tdofs))
    seen = np.zeros(3, dtype=int)
    for step in range(2):
        info = s.solve(b2, x, xref)
        global_kkt(K, b2, x, ndofs, tdofs, lb, xref, bound(law, coef))
        seen += [info["n_active"], info["n_stick"], info["n_slip"]]
        assert info["n_active"] < COMM.allreduce(len(ndofs))           # the ends lift off
        xref = x.array[tdofs].copy()
        b2.axpy(-1.5 * q, drag)
    assert np.all(seen > 0)
    s.destroy()
    x.destroy()
    b2.destroy()


def test_newton_and_fixed_point_agree(block):
    """Coulomb with mu = 0.3 (a unique solution): the Newton method and the fixed point on
    Tresca thresholds, two independent iterations, give the same x."""
    K, b, ndofs, tdofs, lb, _, _ = block
    xs = []
    for method in ("newton", "fixed-point"):
        s = make(Arrays(K, ndofs, tdofs, lb), "coulomb", 0.3, method)
        x = K.createVecRight()
        info = s.solve(b, x, np.zeros(len(tdofs)))
        assert ("outer" in info) == (method == "fixed-point")
        xs.append(x.array.copy())
        s.destroy()
        x.destroy()
    scale = COMM.allreduce(np.max(np.abs(xs[0])), op=MPI.MAX)
    # the fixed point stops when the thresholds move by <= 1e-10 max|b|: x to ~1e-10 of its scale
    assert COMM.allreduce(np.max(np.abs(xs[0] - xs[1])), op=MPI.MAX) <= 1e-8 * scale


def test_mu_zero_is_frictionless(block):
    """Coulomb with mu = 0 is the frictionless problem: the same x and lam_N as
    SemismoothNewton (schur) to round-off, and lam_T = 0."""
    K, b, ndofs, tdofs, lb, _, _ = block
    s = FrictionalNewton(K, ndofs, tdofs, lb, law="coulomb", mu=0.0)
    ref = SemismoothNewton(K, ndofs, lb, linear="schur")
    x, y = K.createVecRight(), K.createVecRight()
    info = s.solve(b, x, np.zeros(len(tdofs)))
    ref.solve(b, y)
    scale = COMM.allreduce(np.max(np.abs(y.array)), op=MPI.MAX)
    assert COMM.allreduce(np.max(np.abs(x.array - y.array)), op=MPI.MAX) <= 1e-12 * scale
    fs = b.norm(PETSc.NormType.NORM_INFINITY)
    assert COMM.allreduce(np.max(np.abs(s.lam - ref.lam), initial=0.0), op=MPI.MAX) <= 1e-12 * fs
    assert np.all(s.lam_t == 0.0) and info["n_stick"] == info["n_slip"] == 0
    for o in (s, ref, x, y):
        o.destroy()


def test_tresca_huge_threshold_sticks(block):
    """Tresca with s = 1e6 (forces ~1e-2): every contact vertex keeps x_t = xref exactly,
    in contact or not."""
    K, b, ndofs, tdofs, lb, _, _ = block
    s = FrictionalNewton(K, ndofs, tdofs, lb, law="tresca", threshold=1e6)
    x = K.createVecRight()
    xref = 0.01 * np.sin(np.arange(len(tdofs)) + 10 * COMM.rank)
    info = s.solve(b, x, xref)
    assert np.all(x.array[tdofs] == xref)
    assert info["n_stick"] == COMM.allreduce(len(tdofs)) and info["n_slip"] == 0
    global_kkt(K, b, x, ndofs, tdofs, lb, xref, bound("tresca", 1e6))
    s.destroy()
    x.destroy()


def test_errors(block):
    """Bad arguments: ValueError naming the problem; too few iterations: VIError."""
    K, b, ndofs, tdofs, lb, _, _ = block
    cases = [(dict(law="stick"), "unknown friction law 'stick'"),
             (dict(law="coulomb"), "coulomb friction needs mu"),
             (dict(law="tresca", threshold=-1.0), "threshold must be finite and >= 0"),
             (dict(law="coulomb", mu=0.3, coulomb="exact"), "unknown Coulomb method 'exact'"),
             (dict(law="coulomb", mu=0.3, c_t=-1.0), "c_t must be >= 0")]
    for kw, msg in cases:
        with pytest.raises(ValueError, match=msg):
            FrictionalNewton(K, ndofs, tdofs, lb, **kw)
    with pytest.raises(ValueError, match="differ in length"):
        FrictionalNewton(K, ndofs, tdofs[:-1] if len(tdofs) else [0], lb, law="tresca", threshold=1.0)
    s = FrictionalNewton(K, ndofs, tdofs, lb, law="coulomb", mu=0.5, coulomb="newton", max_it=1)
    x = K.createVecRight()
    with pytest.raises(ValueError, match="xref_t has shape"):
        s.solve(b, x, np.zeros(len(tdofs) + 1))
    with pytest.raises(VIError, match=r"frictional semi-smooth Newton \(Coulomb\) did not converge in 1 "
                                      r"iterations \(\d+ conditions still violated\)"):
        s.solve(b, x, np.zeros(len(tdofs)))
    s.destroy()
    s = FrictionalNewton(K, ndofs, tdofs, lb, law="coulomb", mu=0.5, coulomb="fixed-point", max_it=2)
    with pytest.raises(VIError, match="did not converge in 2"):
        s.solve(b, x, np.zeros(len(tdofs)))
    s.destroy()
    x.destroy()


def by_coordinates(X, values):
    """Values per vertex (rows of ``values``) gathered on every rank, sorted by coordinates."""
    X, values = np.vstack(COMM.allgather(X)), np.vstack(COMM.allgather(values))
    order = np.lexsort((np.round(X[:, 0], 9), np.round(X[:, 1], 9)))
    return values[order]


def solve_block(comm, law, coef, method, options=None):
    """The elastic block on ``comm``, two steps: per owned vertex (x_x, x_y) after each step,
    per owned bottom vertex (lam_N, lam_T), and the coordinates."""
    K, b, drag, ndofs, tdofs, lb, X = elastic_block(comm=comm)
    b.axpy(0.01, drag)
    s = make(Arrays(K, ndofs, tdofs, lb), law, coef, method, options=options)
    x, xref, out = K.createVecRight(), np.zeros(len(tdofs)), []
    for step in range(2):
        s.solve(b, x, xref)
        out.append(x.array.reshape(-1, 2).copy())
        xref = x.array[tdofs].copy()
        b.axpy(-0.015, drag)
    lam = np.column_stack([s.lam, s.lam_t])
    for o in (s, K, b, drag, x):
        o.destroy()
    return np.hstack(out), lam, X, X[tdofs // 2]


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="compares a 2-rank solve with a serial one: needs mpirun -n 2")
@pytest.mark.parametrize("law,coef,method", [("tresca", 2e-3, None), ("coulomb", 0.5, "newton"),
                                             ("coulomb", 0.5, "fixed-point")])
@pytest.mark.parametrize("redundant", ["1", "0"])
def test_two_ranks_equal_serial(law, coef, method, redundant):
    """The block distributed over the ranks (the factorisation redundant or distributed by
    MUMPS, the dense systems gathered) gives each rank's serial solution to round-off."""
    opts = {"factor_redundant": redundant}
    xp, lamp, Xp, Xcp = solve_block(COMM, law, coef, method, opts)
    xs, lams, Xs, Xcs = solve_block(MPI.COMM_SELF, law, coef, method, opts)
    xp, xs = by_coordinates(Xp, xp), np.asarray(xs)[np.lexsort((np.round(Xs[:, 0], 9), np.round(Xs[:, 1], 9)))]
    assert np.max(np.abs(xp - xs)) <= 1e-12 * np.max(np.abs(xs))
    lamp = by_coordinates(Xcp, lamp)
    lams = lams[np.lexsort((np.round(Xcs[:, 0], 9), np.round(Xcs[:, 1], 9)))]
    assert np.max(np.abs(lamp - lams)) <= 1e-12 * np.max(np.abs(lams))


def test_auto_falls_back_to_fixed_point(block, monkeypatch):
    """``auto`` whose Newton gets one iteration (AUTO_NEWTON_MAX_IT = 1: not enough from
    x = 0) goes on with the fixed point from the step's start and solves the step."""
    monkeypatch.setattr(friction, "AUTO_NEWTON_MAX_IT", 1)
    K, b, ndofs, tdofs, lb, _, _ = block
    s = FrictionalNewton(K, ndofs, tdofs, lb, law="coulomb", mu=0.5, coulomb="auto")
    x = K.createVecRight()
    info = s.solve(b, x, np.zeros(len(tdofs)))
    assert info["outer"] >= 2 and info["its"] > 1 + info["outer"]
    global_kkt(K, b, x, ndofs, tdofs, lb, np.zeros(len(tdofs)), bound("coulomb", 0.5))
    s.destroy()
    x.destroy()


@pytest.mark.parametrize("law,coef", [("tresca", 0.1), ("coulomb", 0.2), ("coulomb", 0.5)])
def test_hsw_rule_with_positive_c_t(law, coef):
    """The set update with a finite c_t (HSW's rule, here c_t = 1, K's diagonal ~ 1) finds
    the chain's solution too."""
    F, P = CHAIN_LOADS[0]
    p = Blocks(chain_matrix(3), F, P, lb=[0.0, -0.1, 0.05])
    s = make(p, law, coef, "newton", c_t=1.0)
    s.solve(p.b, p.x, np.zeros(len(p.tdofs)))
    x = p.gather(p.x.array)
    ref = enumerate_solutions(p.Kg, p.bg, p.lbg, np.zeros(p.m), law, coef)
    assert len(ref) == 1 and np.max(np.abs(x - ref[0])) <= RTOL * np.max(np.abs(ref[0]))
    s.destroy()
    p.destroy()


@pytest.mark.mpi
def test_finish_by_solve_equals_sum_of_columns(block, monkeypatch):
    """x from the cached columns (x0 + sum_j r_j K^-1 e_j) and from one more solve
    K x = b + E r (FINISH_MAX_AXPY = 0, as beyond 100 columns) agree to round-off."""
    K, b, ndofs, tdofs, lb, _, _ = block
    xs = []
    for limit in (friction_system.FINISH_MAX_AXPY, 0):
        monkeypatch.setattr(friction_system, "FINISH_MAX_AXPY", limit)
        s = FrictionalNewton(K, ndofs, tdofs, lb, law="coulomb", mu=0.3)
        x = K.createVecRight()
        s.solve(b, x, np.zeros(len(tdofs)))
        xs.append(x.array.copy())
        s.destroy()
        x.destroy()
    scale = COMM.allreduce(np.max(np.abs(xs[0])), op=MPI.MAX)
    assert COMM.allreduce(np.max(np.abs(xs[0] - xs[1])), op=MPI.MAX) <= 1e-12 * scale
