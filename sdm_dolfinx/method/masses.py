"""Modified masses of the standard pairs (H^h = W^h) and the lumped measure of constrained nodes.

The standard pairs (P1/P1, P2/P2) use the consistent mass M_ij = (rho phi_j, phi_i) of W^h unless
asked otherwise (``Discretisation(..., mass=...)``):

``"row-sum"``: the basic lumped mass, M_L = diag(M 1) (the row sums; GetFEM's ``demo_dynamic_contact_1D``
    "basic lumped mass"). It keeps the total mass and the centre of mass (1^T M_L x = (M 1)^T x =
    1^T M x) but not the second moments, which become the nodal quadrature's: on a simplex of
    dimension d, sum_i m_i f_i g_i - (f, g) = |T| / ((d + 1)(d + 2)) sum_{i<j} (f_i - f_j)(g_i - g_j)
    for affine f, g and P1. P2's vertex functions have zero mean on a triangle and a negative one on a
    tetrahedron (measured: row sums 1e-16 of the largest at the vertices of a P2 triangle mesh,
    -1/20 of the cell's volume per cell on tetrahedra), so the lumped P2 mass is refused there; on an
    interval the P2 row sums are Simpson's weights h/6, 2h/3 (positive, exact for cubics).

``"redistributed"``: the mass redistribution method of H.B. Khenous, P. Laborde, Y. Renard, *Mass
    redistribution method for finite element contact problems in elastodynamics*, Eur. J. Mech.
    A/Solids 27 (2008) 918-932: no inertia at the contact nodes, their mass moved to the other nodes
    so that the total mass, the centre of mass and the moments of inertia are kept; the semi-discrete
    problem is then a well-posed (Lipschitz) system of ODEs at the free nodes and an algebraic
    complementarity at the contact nodes. The paper's text was not reachable from here (HAL and the
    journal were searched for; only the abstract and the 1-D follow-ups of Dabaghi, Petrov, Pousin,
    Renard were found), so the construction below is ours, built to meet exactly the requirements the
    paper states (and the issue repeats):

        M_r = P^T M P,   (P v)_i = v_i at the free nodes,   (P v)_s = sum_j w_sj v_j at a contact node s,

    i.e. the kinetic energy 1/2 (P v)^T M (P v) of a velocity whose contact-node values are
    extrapolated from the free nodes j (weights w_sj). Then (i) M_r's rows and columns vanish exactly
    at the contact nodes (P has zero columns there) and nowhere else ((P e_j)^T M (P e_j) > 0); (ii)
    M_r is symmetric positive semi-definite (a congruence of the SPD M), with Ker M_r = the contact
    nodes' unit vectors exactly, so that condition (7) of Renard (2010) holds with beta = 1; (iii) when
    the weights reproduce affine functions (sum_j w_sj = 1, sum_j w_sj x_j = x_s), P e_a = e_a for
    e_a the nodal interpolant of a in {1, x, y, z}, hence e_a^T M_r e_b = e_a^T M e_b = (rho a, b):
    total mass, centre of mass and second moments (the inertia tensor) are those of the consistent
    M -- for P1 and P2 Lagrange (any degree), in 1-D, 2-D and 3-D. A vector problem gives every
    component the same scalar M_r (a contact node has no inertia in any direction, as in the paper).

    Choices the requirements leave open, and ours: the donors of a contact node s are the free nodes
    (neither contact nor Dirichlet nodes: a Dirichlet node's velocity is 0, so mass given to it would
    be lost) within the smallest number of cell rings around s (1, 2, ... up to :data:`MAX_RINGS`)
    whose positions span an affine space of the mesh's dimension (a P1 contact vertex on a flat
    boundary needs two rings: its first ring's free vertices are collinear); among the affine-
    reproducing weights we take the minimum-norm ones (negative weights are unavoidable when s lies
    outside the convex hull of its donors, as a boundary node does; positivity of M_r does not need
    them positive). The 1-D P1 rod contact node x_0 thus moves with 2 v_1 - v_2. The weights are
    computed on rank 0 from the gathered mesh (global numbering), so 1 and 2 ranks build the same M_r
    up to round-off; M_r = P^T M P is PETSc's distributed PtAP, symmetrised, on a pattern that holds
    M's (the integrator adds A into a copy of M).

:func:`nodal_measure` is the lumped measure of every constrained node when the constraint acts at
every dof of W^h on the constrained boundary (``constrain="nodes"``, see
:class:`~sdm_dolfinx.method.discretisation.Discretisation`); :func:`product` is how a Discretisation
multiplies by its M (any pair and mass).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl

from sdm_dolfinx import compat
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.mpiutil import gather_rows

#: the masses of this module (the others are the consistent mass or an SDM pair's C treatment)
MODIFIED = ("row-sum", "redistributed")
#: a row sum (a nodal measure) at or below this times the largest one counts as zero: a node
#: without mass; P2 triangles give 1e-16 (round-off of an exact 0)
ZERO_TOL = 1e-12
#: cell rings around a contact node searched for its donors (two are needed for P1 on a flat
#: boundary, one for P2; more means a constrained region without free nodes in it)
MAX_RINGS = 4


def singular(B, c):
    """M = B^T C^-1 B for C = diag(``c``) (the product of B^T and C^-1 B)."""
    cinv = c.copy()
    cinv.reciprocal()
    Bs = B.copy()
    Bs.diagonalScale(L=cinv)                  # C^-1 B
    Bt = B.transpose(PETSc.Mat())    # not in place; not MatTransposeMatMult (its MPI memory: bench/README)
    M = Bt.matMult(Bs)
    Bt.destroy(), Bs.destroy()
    return M


def diagonal(disc):
    """The diagonal of M (a vector of W^h's layout) without forming M when it is B^T C^-1 B with
    C = diag(c): diag(M)_j = sum_i B_ij^2 / c_i; else M's own."""
    if disc.B is None or disc.c_lumped is None:
        return disc.M.getDiagonal()
    ai, aj, av = disc.B.getValuesCSR()
    squares = PETSc.Mat().createAIJ(disc.B.getSizes(), csr=(ai, aj, av * av), comm=disc.comm)
    cinv = disc.c_lumped.copy()
    cinv.reciprocal()
    out = disc.A.createVecLeft()
    squares.multTranspose(cinv, out)
    squares.destroy()
    return out


def build(disc):
    """The modified mass of ``disc.mass`` (:data:`MODIFIED`) from the consistent ``disc.M``."""
    if disc.mass == "row-sum":
        return row_sum(disc.M, disc.pair.name, compat.cell_name(disc.problem.mesh))
    return redistributed(disc)


def product(disc):
    """The fastest ``mult(x, y)``: y = M x for the Discretisation ``disc``.

    M itself, or B^T (D^-1 (B x)) when M = B^T D^-1 B is much denser than B (P2/P1: 3
    products per step with M cost as much as the step's solve; through B, a third), or
    for the consistent variant (M never formed) B^T C^-1 B x with a solve with C.
    """
    if disc.M is None:
        return disc._consistent_mass_mult
    if disc.B is None or disc.c_lumped is None:
        return disc.M.mult
    local = PETSc.Mat.InfoType.LOCAL
    nz = disc.comm.allreduce(np.array([disc.M.getInfo(local)["nz_used"], disc.B.getInfo(local)["nz_used"]]),
                             op=MPI.SUM)
    if nz[0] <= 3 * nz[1]:
        return disc.M.mult
    return through_b(disc)


def through_b(disc):
    """``mult(x, y)``: y = B^T (D^-1 (B x)) = M x for a pair with a diagonal C = D, M never formed."""
    h = disc.B.createVecLeft()

    def mult(x, y):
        disc.B.mult(x, h)
        h.pointwiseDivide(h, disc.c_lumped)
        disc.B.multTranspose(h, y)
    return mult


def _reduced(comm, value, op):
    return comm.allreduce(float(value), op=op)


def row_sum(M, pair="", cell=""):
    """M_L = diag(M 1) on M's nonzero pattern (zeros off the diagonal: A's pattern stays a subset).

    Raises:
        DiscretisationError: a row sum is not positive (P2 on triangles and tetrahedra).
    """
    comm = M.getComm().tompi4py()
    ones = M.createVecRight()
    ones.set(1.0)
    d = M.createVecLeft()
    M.mult(ones, d)
    lo = _reduced(comm, np.min(d.array, initial=np.inf), MPI.MIN)
    hi = _reduced(comm, np.max(d.array, initial=-np.inf), MPI.MAX)
    if lo <= ZERO_TOL * hi:
        raise DiscretisationError(
            f"mass 'row-sum' is not available for pair {pair} on {cell} meshes: the row sums of its mass "
            f"matrix are not all positive (smallest {lo:.3g}, {lo / hi:.2g} times the largest: the vertex functions "
            f"of P2 have zero mean on a triangle, a negative one on a tetrahedron), so the lumped mass would "
            f"leave nodes without mass; use mass 'standard' or 'redistributed', or the singular-mass pair P2/P1")
    L = M.copy()
    L.zeroEntries()
    L.setDiagonal(d)
    L.assemble()
    ones.destroy(), d.destroy()
    return L


# ----------------------------------------------------------------------- redistribution
def extrapolation_weights(x, cells, contact, excluded, tdim):
    """Affine-reproducing extrapolation weights of every contact node from the free nodes near it.

    Pure NumPy/SciPy on global data (rank 0). Args: ``x`` (n, gdim) node coordinates; ``cells``
    (ncells, k) node indices of each cell; ``contact`` the contact nodes; ``excluded`` nodes that may
    not carry mass (Dirichlet); ``tdim`` the mesh's dimension.

    Returns:
        ``(rows, cols, weights)``: (P v)_s = sum of weights * v_cols over the entries with rows == s;
        or a string: why a contact node has no donors (for a one-line error).
    """
    import scipy.sparse as sp
    n = x.shape[0]
    ncells, k = cells.shape
    inc = sp.csr_matrix((np.ones(ncells * k), (np.repeat(np.arange(ncells), k), cells.reshape(-1))),
                        shape=(ncells, n))
    adj = (inc.T @ inc).tocsr()                         # nodes sharing a cell (and each node itself)
    free = np.ones(n, dtype=bool)
    free[contact] = False
    free[excluded] = False
    rows, cols, vals = [], [], []
    for s in np.asarray(contact, dtype=np.int64):
        w = _weights(adj, free, x, s, tdim)
        if w is None:
            where = ", ".join(f"{c:.6g}" for c in x[s])
            return (f"mass 'redistributed': the contact node at ({where}) has no free nodes spanning its "
                    f"neighbourhood within {MAX_RINGS} cell rings (every node near it is constrained or a "
                    f"Dirichlet node) to take its mass; use a pair whose W^h has free nodes there (P2/P2 "
                    f"with the vertex constraint) or a singular-mass pair")
        donors, weights = w
        rows.append(np.full(len(donors), s))
        cols.append(donors)
        vals.append(weights)
    if not rows:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)


def _weights(adj, free, x, s, tdim):
    """(donors, minimum-norm affine-reproducing weights) of contact node ``s``, or None."""
    ring = np.array([s])
    for _ in range(MAX_RINGS):
        ring = np.unique(adj[ring].indices)
        donors = ring[free[ring]]
        if len(donors) < tdim + 1:
            continue
        A = np.vstack([np.ones(len(donors)), x[donors].T])        # (1 + gdim) x donors
        sv = np.linalg.svd(A, compute_uv=False)
        if np.sum(sv > sv[0] * 1e-10) < tdim + 1:
            continue                                                # donors on a line (plane): go on
        b = np.concatenate([[1.0], x[s]])
        w = np.linalg.lstsq(A, b, rcond=1e-10)[0]                   # minimum norm among exact solutions
        if np.linalg.norm(A @ w - b) <= 1e-10 * np.linalg.norm(b):
            return donors, w
    return None


def _global_mesh(disc):
    """Node (block) coordinates, cells as global node numbers, the contact and the Dirichlet nodes:
    gathered on rank 0 (None elsewhere). Collective."""
    W, comm, msh = disc.W, disc.comm, disc.problem.mesh
    imap, bs = W.dofmap.index_map, W.dofmap.index_map_bs
    nloc, off = imap.size_local, imap.local_range[0]
    ncells = msh.topology.index_map(msh.topology.dim).size_local
    local = compat.dofmap_list(W)[:ncells]
    cells = imap.local_to_global(local.reshape(-1).astype(np.int32)).reshape(local.shape)
    x = W.tabulate_dof_coordinates()[:nloc, :msh.geometry.dim]
    return [gather_rows(a, comm) for a in (x, cells, np.unique(disc.cdofs // bs) + off,
                                            np.unique(disc.ddofs // bs) + off)]


def redistributed(disc):
    """M_r = P^T M P (module docstring) from the consistent ``disc.M`` and ``disc.cdofs``.

    Raises:
        DiscretisationError: a contact node without donors (one line, on every rank).
    """
    W, comm = disc.W, disc.comm
    imap, bs = W.dofmap.index_map, W.dofmap.index_map_bs
    x, cells, contact, excluded = _global_mesh(disc)
    result = None
    if comm.rank == 0:
        result = extrapolation_weights(x, cells, contact, excluded, disc.problem.mesh.topology.dim)
    error = comm.bcast(result if isinstance(result, str) else None, root=0)
    if error:
        raise DiscretisationError(error)
    ranges = comm.allgather(imap.local_range)
    send = None
    if comm.rank == 0:
        rows, cols, vals = result
        send = [(rows[m], cols[m], vals[m]) for m in ((rows >= a) & (rows < b) for a, b in ranges)]
    rows, cols, vals = comm.scatter(send, root=0)
    P = _extrapolation(imap, bs, comm, rows, cols, vals)
    Mr = disc.M.PtAP(P)
    Mt = Mr.transpose()
    Mr.axpy(1.0, Mt, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    Mr.scale(0.5)                                   # exactly symmetric (PtAP sums in two orders)
    R = disc.M.copy()                               # M's pattern (= A's) plus the redistribution's
    R.zeroEntries()
    R.axpy(1.0, Mr, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    for m in (P, Mr, Mt):
        m.destroy()
    return R


def _extrapolation(imap, bs, comm, rows, cols, vals):
    """The distributed P (dim W x dim W): identity at free dofs, the weights at contact nodes' dofs
    (the same for every component)."""
    nloc, off = imap.size_local, imap.local_range[0]
    n = nloc * bs
    N = imap.size_global * bs
    indptr, indices, data = [0], [], []
    order = np.argsort(rows, kind="stable")
    rows, cols, vals = rows[order], cols[order], vals[order]
    starts = np.searchsorted(rows, np.arange(off, off + nloc + 1))
    for b in range(nloc):
        lo, hi = starts[b], starts[b + 1]
        for c in range(bs):
            if hi > lo:
                k = np.argsort(cols[lo:hi])
                indices.append(cols[lo:hi][k] * bs + c)
                data.append(vals[lo:hi][k])
            else:
                indices.append(np.array([(off + b) * bs + c]))
                data.append(np.ones(1))
            indptr.append(indptr[-1] + len(indices[-1]))
    csr = (np.asarray(indptr, dtype=PETSc.IntType),
           np.concatenate(indices).astype(PETSc.IntType) if indices else np.zeros(0, PETSc.IntType),
           np.concatenate(data).astype(PETSc.ScalarType) if data else np.zeros(0))
    P = PETSc.Mat().createAIJ(size=((n, N), (n, N)), csr=csr, comm=comm)
    P.assemble()
    return P


# ----------------------------------------------------------------------- nodal measure
def nodal_measure(disc, dofs):
    """The lumped measure of the constrained boundary at the owned W^h dofs ``dofs`` (stress =
    nodal multiplier / measure), from the problem's ``constraint_measure`` in W^h's own basis.

    The row sums m_i = constraint_measure(phi_i) are the consistent choice: a uniform stress s gives
    the nodal forces s m_i, so lam_i / m_i = s at every node; for P2 on a 2-D body's boundary edges
    they are h/6 at a vertex (per edge) and 2h/3 at a mid-edge node. Where some vanish (P2 on the
    triangles of a 3-D body's boundary, or a domain measure on triangles: 0 at the vertices) the
    boundary mass is lumped by HRZ instead (its diagonal scaled to the same total): positive, but a
    uniform stress then reads as 0 at the vertices (their nodal forces are 0) and 19/16 s at the
    mid-edge nodes.
    """
    p, W = disc.problem, disc.W
    comp = p.constraint_component or 0
    pick = (lambda f: f[comp]) if p.shape else (lambda f: f)
    q = ufl.TestFunction(W)
    m = compat.assemble_vector(disc.form(p.constraint_measure(pick(q))))
    vals = np.array(m.array[dofs])
    comm = disc.comm
    lo = _reduced(comm, np.min(vals, initial=np.inf), MPI.MIN)
    hi = _reduced(comm, np.max(vals, initial=0.0), MPI.MAX)
    if lo > ZERO_TOL * hi:
        m.destroy()
        return vals
    u = ufl.TrialFunction(W)
    Mb = compat.assemble_matrix(disc.form(p.constraint_measure(pick(u) * pick(q))))
    diag = Mb.getDiagonal()
    total, dsum = comm.allreduce(np.array([m.array.sum(), diag.array.sum()]), op=MPI.SUM)
    out = np.array(diag.array[dofs]) * (total / dsum)
    for obj in (m, Mb, diag):
        obj.destroy()
    return out
