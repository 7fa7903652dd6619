"""Well-posedness inspector: measures the inf-sup condition (7) of the paper for a Problem and a Pair.

Condition (7) (Renard 2010, section 2) asks that the constraint map G (rows G^i, g^i(w) = (G^i)^T W)
be surjective on F = Ker(B):

    beta = inf_{Q != 0} sup_{W in Ker(B), W != 0} Q^T G W / (|Q| |W|) > 0,

with |.| the Euclidean norm of coefficient vectors, so beta depends on the basis scaling (dolfinx's P1+
basis, for instance, has vertex functions that vanish at the centroid). Since sup_{W in F} Q^T G W / |W|
= |P_F G^T Q|, beta^2 is the smallest eigenvalue of S = G P_F G^T, P_F the orthogonal projector on
Ker(B). Here G's rows are unit vectors at the constrained dofs -- the constrained vertices (eq. (13)), or
with ``constrain="nodes"`` every dof of W^h on the constrained boundary (P2's mid-edge nodes too) -- so S
is the principal submatrix of P_F at those dofs (so beta with the vertex constraint is at least beta with
the node constraint: Cauchy's interlacing). W^h is the space without the Dirichlet dofs (section 3: "A is
the set of vertices not on Gamma_D"), so B (and G) lose those columns; H^h keeps all its dofs, except in
standard Galerkin where H^h = W^h.

Two ways to compute it (the report says which ran); all linear algebra runs on rank 0 on the gathered
global matrices, so 1 and 2 ranks give the same numbers up to round-off:

- dense (dim W^h <= ``dense_max``): an SVD of B gives rank(B) and an orthonormal basis Z of Ker(B);
  beta = sigma_min(Z[c, :]), exact to round-off even near 0;
- iterative (larger): SuperLU factorisation of the Gram matrix B B^T (or B^T B when dim H^h > dim W^h),
  shift-invert ARPACK (SciPy ``eigsh``) for its extreme eigenvalues (surjectivity of B), and
  S = I - Y^T (B B^T)^-1 Y with Y = B G^T, formed densely for N_g <= ``dense_max`` or else ARPACK on S.
  S's smallest eigenvalue is then accurate to about eps, so beta resolves down to about sqrt(eps).

The report, the sweep table and the beta-h plot: :mod:`.infsup_report`; the command line:
``python -m sdm_dolfinx inspect membrane --pair P2/P1 --N 8 [--sweep] [--json F]`` (:mod:`sdm_dolfinx.cli.inspect`).
"""
import gc
import math
import time

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx.analysis.repeated_rows import distinct_rows
from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.pairs import get_pair
from sdm_dolfinx.mpiutil import gather_rows

EPS = np.finfo(float).eps
#: beta <= TOL counts as beta = 0: the iterative path resolves beta only to about sqrt(eps) (it gets
#: beta^2 as an eigenvalue accurate to about eps), 100 sqrt(eps) ~ 1.5e-6 leaves a margin of 100
TOL = 100.0 * math.sqrt(EPS)
#: above this dim W^h (columns of B) the dense SVD (reference BLAS here: ~2.5 s at 600 x 1500) gives way
#: to the iterative path
DENSE_MAX = 1500
#: on the iterative path, sigma_min(B) / sigma_max(B) below this counts as rank deficient (the Gram
#: matrix's eigenvalues are accurate to about eps lambda_max, so sigma ratios to about sqrt(eps))
RANK_TOL = 100.0 * math.sqrt(EPS)


class InspectError(SdmError, RuntimeError):
    """The measurement cannot be made (e.g. B rank deficient beyond the dense path's size)."""


# ---------------------------------------------------------------------------- gathering to rank 0
def _gather_csr(A, comm):
    """The distributed PETSc matrix A as a SciPy CSR matrix (global numbering) on rank 0, None elsewhere."""
    import scipy.sparse as sp
    r0, r1 = A.getOwnershipRange()
    indptr, indices, data = A.getValuesCSR()
    rows = gather_rows(np.repeat(np.arange(r0, r1, dtype=np.int64), np.diff(indptr)), comm)
    cols = gather_rows(np.asarray(indices, dtype=np.int64), comm)
    vals = gather_rows(np.asarray(data, dtype=float), comm)
    if comm.rank != 0:
        return None
    M = sp.csr_matrix((vals, (rows, cols)), shape=A.getSize())
    M.eliminate_zeros()
    return M


def _gather_global(local, offset, comm):
    """Owned local indices + this rank's global offset, gathered and sorted on rank 0 (None elsewhere)."""
    parts = gather_rows(np.asarray(local, dtype=np.int64) + offset, comm)
    return np.sort(parts) if comm.rank == 0 else None


def cell_diameter(msh):
    """The largest cell diameter h of the mesh (over all ranks), from the cells' vertex coordinates."""
    tdim = msh.topology.dim
    ncells = msh.topology.index_map(tdim).size_local
    h = 0.0
    if ncells:
        nodes = compat.mesh_geometry_dofmap(msh)[:ncells, :tdim + 1]      # vertices come first
        x = msh.geometry.x[nodes]                                          # (cells, tdim + 1, 3)
        for i in range(tdim + 1):
            for j in range(i + 1, tdim + 1):
                h = max(h, float(np.max(np.linalg.norm(x[:, i] - x[:, j], axis=1))))
    return msh.comm.allreduce(h, op=MPI.MAX)


def operators(disc):
    """(B, C, cidx, n_dirichlet) on rank 0 for condition (7), (None, None, None, n) elsewhere.

    B: N_H x dim W^h (SciPy CSR) without the Dirichlet columns (and rows, in standard Galerkin where
    H^h = W^h and B is W's mass matrix); C: the consistent N_H x N_H matrix (psi_i, psi_j); cidx:
    the constrained columns of B (G's unit rows), in the reduced numbering.
    """
    comm = disc.comm
    W = disc.W
    bs = W.dofmap.index_map_bs
    off = W.dofmap.index_map.local_range[0] * bs
    n_total = W.dofmap.index_map.size_global * bs
    standard = disc.B is None
    Bfull = _gather_csr(disc.M if standard else disc.B, comm)
    Cfull = None if standard else _gather_csr(disc.C, comm)
    dirichlet = _gather_global(disc.ddofs, off, comm)
    constrained = _gather_global(disc.cdofs, off, comm)
    n_dir = comm.bcast(None if dirichlet is None else len(dirichlet), root=0)
    if comm.rank != 0:
        return None, None, None, n_dir
    keep = np.setdiff1d(np.arange(n_total, dtype=np.int64), dirichlet)
    B = Bfull[:, keep].tocsr()
    if standard:
        B = B[keep, :].tocsr()
        C = B
    else:
        C = Cfull
    cidx = np.searchsorted(keep, constrained)
    assert np.array_equal(keep[cidx], constrained), "a constrained dof is also a Dirichlet dof"
    return B, C, cidx, n_dir


def gap_matrix(disc):
    """The gap rows of ``disc`` as a SciPy CSR matrix on rank 0 (global columns of W^h, None elsewhere),
    or None on every rank for the unit rows of ``cdofs``: the weighted gap's G; against obstacles the
    rows at the reference configuration (U = 0, t = 0: each node's normal there); between bodies (contact
    pairs) the rows of the reference configuration, slave and master columns. Collective."""
    import scipy.sparse as sp
    comm = disc.comm
    if getattr(disc, "weighted_rows", None) is not None:
        return _gather_csr(disc.weighted_rows.G, comm)
    rows = disc.obstacle_rows
    bodies = getattr(disc, "body_rows", None)
    if rows is None and bodies is None:
        return None
    bs = disc.W.dofmap.index_map_bs
    off = disc.W.dofmap.index_map.local_range[0] * bs
    zero = np.zeros(disc.W.dofmap.index_map.size_local * bs)
    if bodies is not None:              # between bodies: the rows at U = 0 (global columns already)
        (ids, coef), _ = bodies.rows(zero, 0.0, 0.0, None)
    else:
        coef, _ = rows.rows(zero, 0.0, 0.0, None)
        ids = off + rows.dofs
    m, k = coef.shape
    first = comm.exscan(m) or 0
    r = gather_rows(np.repeat(first + np.arange(m, dtype=np.int64), k), comm)
    c = gather_rows(np.asarray(ids).reshape(-1).astype(np.int64), comm)
    v = gather_rows(coef.reshape(-1), comm)
    n = comm.allreduce(m)
    if comm.rank != 0:
        return None
    G = sp.csr_matrix((v, (r, c)), shape=(n, _w_size(disc)))
    G.eliminate_zeros()
    return G


def _w_size(disc):
    """dim W^h (every dof)."""
    return disc.W.dofmap.index_map.size_global * disc.W.dofmap.index_map_bs



# ------------------------------------------------------------------------------ linear algebra
def measure(B, C, cidx, tol=TOL, dense_max=DENSE_MAX):
    """Condition (7) for B (N_H x N_W), C (N_H x N_H, SPD) and constrained columns ``cidx``.

    Pure SciPy/NumPy (no MPI): the numbers of :func:`inspect`. Returns a dict (see :func:`inspect`).
    """
    import scipy.sparse as sp
    B = sp.csr_matrix(B)
    nH, nW = B.shape
    repeated = 0
    if sp.issparse(cidx):           # general rows G (the weighted gap, obstacles' normals)
        cidx = sp.csr_matrix(cidx)
        keep = distinct_rows(cidx)
        repeated = cidx.shape[0] - len(keep)
        cidx = cidx[keep] if repeated else cidx
        Ng = cidx.shape[0]
    else:                           # unit rows at the constrained dofs
        cidx = np.asarray(cidx, dtype=np.int64)
        Ng = len(cidx)
        if len(np.unique(cidx)) != Ng:
            raise InspectError("the constraint set lists a dof twice: the g^i are not linearly independent")
    t0 = time.perf_counter()
    r = _dense(B, C, cidx, tol) if nW <= dense_max else _iterative(B, cidx, dense_max, tol)
    r.update(dim_W=int(nW), dim_H=int(nH), N_g=int(Ng))
    dimF = r["dim_ker_B"]
    r["B_surjective"] = r["rank_B"] == nH
    r["B_injective"] = dimF == 0
    r["M_singular"] = r["rank_M"] < nW
    r["count_condition"] = bool(nH <= nW - Ng)         # the paper's consequence of (7) (B surjective)
    r["kernel_condition"] = bool(dimF >= Ng)           # dim Ker(B) >= N_g, necessary in any case
    r["tolerance"] = tol
    r["seconds"] = time.perf_counter() - t0
    r["verdict"], r["reason"] = _verdict(r, tol)
    r["repeated_rows"] = repeated
    if repeated:
        r["reason"] += (f"; measured on the N_g = {Ng} distinct rows: {repeated} more repeat some of them (the same "
                        f"constraint twice, e.g. the two passes of a node-to-surface contact where vertices meet: "
                        f"the constraint set is the same, their force splits)")
    return r


def _rank(s, shape):
    """Numerical rank from singular values s (descending): NumPy's rule sigma > sigma_max max(m, n) eps."""
    if s.size == 0 or s[0] <= 0:
        return 0
    return int(np.sum(s > s[0] * max(shape) * EPS))


def _dense(B, C, cidx, tol):
    import scipy.linalg as sl
    Bd = B.toarray()
    nH, nW = Bd.shape
    if min(nH, nW) == 0:
        s, Vt = np.zeros(0), np.eye(nW)
    else:
        _, s, Vt = sl.svd(Bd, full_matrices=True)
    rank = _rank(s, Bd.shape)
    Z = Vt[rank:].T                                    # orthonormal basis of Ker(B) (= F)
    Ng, dimF = cidx.shape[0], nW - rank
    zeros = None                                       # number of zero eigenvalues of G P_F G^T, if known
    if Ng == 0:
        beta = None                                    # inf over an empty set: (7) holds vacuously
    elif dimF < Ng:
        beta = 0.0                                     # rank(G P_F G^T) <= dim F < N_g
        zeros = Ng - dimF if dimF == 0 else None
    else:
        GZ = cidx @ Z if not isinstance(cidx, np.ndarray) else Z[cidx]
        sv = sl.svdvals(GZ)                            # sigma(G Z) = sqrt(eigenvalues of G P_F G^T)
        beta = float(sv[-1])
        zeros = int(np.sum(sv <= tol))
    # M = B^T C^-1 B = X^T X with X = L^-1 B, C = L L^T: rank(M) = rank(X), measured, not assumed
    if min(nH, nW) == 0:
        rank_M = 0
    else:
        L = sl.cholesky(C.toarray(), lower=True)
        X = sl.solve_triangular(L, Bd, lower=True)
        rank_M = _rank(sl.svdvals(X), X.shape)
    smin = float(s[min(nH, nW) - 1] / s[0]) if s.size and s[0] > 0 else 0.0
    return {"beta": beta, "method": "dense: LAPACK SVD of B, beta = sigma_min of the Ker(B) basis at the "
                                    "constrained dofs", "method_short": "dense",
            "rank_B": rank, "dim_ker_B": dimF, "rank_M": rank_M, "rank_M_method": "measured (SVD of L^-1 B)",
            "sigma_ratio_B": smin, "zero_modes": zeros}


def _iterative(B, cidx, dense_max, tol):
    import scipy.sparse.linalg as sla
    try:
        return _iterative_arpack(B, cidx, dense_max, tol)
    except sla.ArpackNoConvergence as e:
        raise InspectError(f"ARPACK did not converge ({e}); rerun with --dense-max {B.shape[1]} (slow)") from None


def _iterative_arpack(B, cidx, dense_max, tol):
    import scipy.sparse.linalg as sla
    nH, nW = B.shape
    Ng = cidx.shape[0]
    unit = isinstance(cidx, np.ndarray)
    wide = nH <= nW
    K = ((B @ B.T) if wide else (B.T @ B)).tocsc()      # Gram matrix of the smaller side
    n = K.shape[0]
    rng = np.random.default_rng(0)                      # a generic but reproducible ARPACK start
    v0 = rng.standard_normal(n)
    lam_max = sla.eigsh(K, k=1, which="LA", v0=v0, return_eigenvectors=False)[0]
    try:
        lu = sla.splu(K)
    except RuntimeError:                                # exactly singular
        lu, lam_min = None, 0.0
    if lu is not None:
        inv = sla.LinearOperator(K.shape, matvec=lu.solve, dtype=float)
        lam_min = sla.eigsh(K, k=1, sigma=0.0, which="LM", OPinv=inv, v0=v0, return_eigenvectors=False)[0]
    ratio = math.sqrt(max(lam_min, 0.0) / lam_max) if lam_max > 0 else 0.0
    if ratio <= RANK_TOL:
        raise InspectError(f"B is numerically rank deficient (sigma_min/sigma_max = {ratio:.2e}); its kernel "
                           f"needs the dense SVD: rerun with --dense-max {nW} (slow)")
    rank = nH if wide else nW
    dimF = nW - rank
    method = ("iterative: SuperLU of B B^T, ARPACK (SciPy eigsh) for its extreme eigenvalues; "
              if wide else "iterative: SuperLU of B^T B, ARPACK (SciPy eigsh) for its extreme eigenvalues; ")
    zeros = None
    if Ng == 0:
        beta = None
    elif dimF < Ng:
        beta, method = 0.0, method + "beta = 0 since dim Ker(B) < N_g"
        zeros = Ng if dimF == 0 else None
    else:
        # P_F = I - B^T (B B^T)^-1 B, so S = G P_F G^T = G G^T - Y^T (B B^T)^-1 Y, Y = B G^T (G G^T = I
        # for unit rows)
        Y = B[:, cidx].tocsc() if unit else (B @ cidx.T).tocsc()
        GGt = np.eye(Ng) if unit else (cidx @ cidx.T).toarray() if Ng <= dense_max else None
        if Ng <= dense_max:
            S = GGt - Y.T @ lu.solve(Y.toarray())
            lams = np.linalg.eigvalsh(0.5 * (S + S.T))
            lam, zeros = float(lams[0]), int(np.sum(lams <= tol ** 2))
            method += "S = G P_F G^T formed densely (LAPACK eigvalsh)"
        else:
            gg = (lambda q: q) if unit else (lambda q: cidx @ (cidx.T @ q))
            S = sla.LinearOperator((Ng, Ng), matvec=lambda q: gg(q) - Y.T @ lu.solve(Y @ q), dtype=float)
            lam = float(sla.eigsh(S, k=1, which="SA", v0=rng.standard_normal(Ng), ncv=min(Ng, 64),
                                  maxiter=100 * Ng, return_eigenvectors=False)[0])
            method += "ARPACK (SciPy eigsh) for the smallest eigenvalue of S = G P_F G^T"
        beta = math.sqrt(max(lam, 0.0))
    return {"beta": beta, "method": method, "method_short": "iterative", "rank_B": rank, "dim_ker_B": dimF,
            "rank_M": rank, "rank_M_method": "rank(B): C is SPD, so Ker(M) = Ker(B)", "sigma_ratio_B": ratio,
            "zero_modes": zeros}


def _verdict(r, tol):
    """('well-posed' | 'ill-posed', reason) from the measured numbers."""
    nW, nH, Ng, dimF = r["dim_W"], r["dim_H"], r["N_g"], r["dim_ker_B"]
    count = f"dim H^h = {nH} {'<=' if r['count_condition'] else '>'} dim W^h - N_g = {nW - Ng}"
    if Ng == 0:
        return "well-posed", "no constraints (N_g = 0): condition (7) holds vacuously"
    if dimF == 0:
        return "ill-posed", (f"Ker(B) = {{0}} (B injective, M = B^T C^-1 B invertible): no W in Ker(B) carries "
                             f"the {Ng} constraints; count condition {count}")
    if dimF < Ng:
        return "ill-posed", (f"dim Ker(B) = {dimF} < N_g = {Ng}: G cannot be surjective on Ker(B); "
                             f"count condition {count}")
    if r["beta"] <= tol:
        modes = "" if r.get("zero_modes") is None else f" (G P_F G^T has {r['zero_modes']} zero eigenvalue(s))"
        return "ill-posed", (f"G is not surjective on Ker(B): beta = {r['beta']:.3e} <= tol = {tol:.1e}{modes} "
                             f"although dim Ker(B) = {dimF} >= N_g = {Ng}")
    return "well-posed", f"beta = {r['beta']:.6g} > tol = {tol:.1e} (condition (7)); count condition {count}"


# ---------------------------------------------------------------------------------- MPI driver
def inspect(problem, pair, tol=TOL, dense_max=DENSE_MAX, constrain="vertices"):
    """Condition (7) for ``problem`` discretised with ``pair`` (a name or a Pair), the constraint K^h
    at ``constrain`` (``"vertices"``, eq. (13), or ``"nodes"``: every dof of W^h on the constrained
    boundary, see :class:`~sdm_dolfinx.method.discretisation.Discretisation`); the same dict on every rank.

    Keys: dim_W (W^h, Dirichlet dofs removed), dim_W_total, n_dirichlet, dim_H, N_g, rank_B, dim_ker_B,
    B_surjective, B_injective, rank_M, M_singular, count_condition (dim H <= dim W - N_g),
    kernel_condition (dim Ker(B) >= N_g), beta (None if N_g = 0), method, tolerance, verdict, reason, h,
    constrain.
    """
    pair = get_pair(pair) if isinstance(pair, str) else pair
    disc = Discretisation(problem, pair, constrain=constrain)
    comm = disc.comm
    h = cell_diameter(problem.mesh)
    B, C, cidx, n_dir = operators(disc)
    G = gap_matrix(disc)    # on rank 0
    if disc.weighted_rows is not None or disc.obstacle_rows is not None or disc.body_rows is not None:
        # general rows, without Dirichlet columns
        dirichlet = _gather_global(disc.ddofs, disc.W.dofmap.index_map.local_range[0] * disc.W.dofmap.index_map_bs,
                                   comm)
        if comm.rank == 0:
            cidx = G[:, np.setdiff1d(np.arange(G.shape[1], dtype=np.int64), dirichlet)].tocsr()
    result, error = None, None
    if comm.rank == 0:
        try:
            result = measure(B, C, cidx, tol=tol, dense_max=dense_max)
        except InspectError as e:
            error = str(e)
    del disc, B, C
    gc.collect()        # PETSc destructors are collective: free this Discretisation on every rank now
    error = comm.bcast(error, root=0)
    if error is not None:
        raise InspectError(error)
    result = comm.bcast(result, root=0)
    result.update(pair=pair.name, paper=pair.well_posed, problem=problem.name,
                  parameters=dict(problem.parameters), h=h, n_dirichlet=n_dir,
                  dim_W_total=result["dim_W"] + n_dir, ranks=comm.size, constrain=constrain)
    return result


def sweep(make_problem, values, pairs, tol=TOL, dense_max=DENSE_MAX, progress=None, constrain="vertices"):
    """inspect() for each mesh ``make_problem(value)`` and each pair: a list of result dicts."""
    rows = []
    for v in values:
        for pair in pairs:
            r = inspect(make_problem(v), pair, tol=tol, dense_max=dense_max, constrain=constrain)
            r["sweep_value"] = v
            rows.append(r)
            if progress:
                progress(r)
    return rows
