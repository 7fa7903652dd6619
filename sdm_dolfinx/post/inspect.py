"""Well-posedness inspector: measures the inf-sup condition (7) of the paper for a Problem and a Pair.

Condition (7) (Renard 2010, section 2) asks that the constraint map G (rows G^i, g^i(w) = (G^i)^T W)
be surjective on F = Ker(B):

    beta = inf_{Q != 0} sup_{W in Ker(B), W != 0} Q^T G W / (|Q| |W|) > 0,

with |.| the Euclidean norm of coefficient vectors, so beta depends on the basis scaling (dolfinx's P1+
basis, for instance, has vertex functions that vanish at the centroid). Since sup_{W in F} Q^T G W / |W|
= |P_F G^T Q|, beta^2 is the smallest eigenvalue of S = G P_F G^T, P_F the orthogonal projector on
Ker(B). Here G's rows are unit vectors at the constrained vertex dofs (eq. (13)), so S is the principal
submatrix of P_F at those dofs. W^h is the space without the Dirichlet dofs (section 3: "A is the set of
vertices not on Gamma_D"), so B (and G) lose those columns; H^h keeps all its dofs, except in standard
Galerkin where H^h = W^h.

Two ways to compute it (the report says which ran); all linear algebra runs on rank 0 on the gathered
global matrices, so 1 and 2 ranks give the same numbers up to round-off:

- dense (dim W^h <= ``dense_max``): an SVD of B gives rank(B) and an orthonormal basis Z of Ker(B);
  beta = sigma_min(Z[c, :]), exact to round-off even near 0;
- iterative (larger): SuperLU factorisation of the Gram matrix B B^T (or B^T B when dim H^h > dim W^h),
  shift-invert ARPACK (SciPy ``eigsh``) for its extreme eigenvalues (surjectivity of B), and
  S = I - Y^T (B B^T)^-1 Y with Y = B G^T, formed densely for N_g <= ``dense_max`` or else ARPACK on S.
  S's smallest eigenvalue is then accurate to about eps, so beta resolves down to about sqrt(eps).

Command line: ``python -m sdm_dolfinx inspect --problem membrane --pair P2/P1 --N 8 [--sweep] [--json F]``.
"""
import argparse
import gc
import json
import math
import os
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

from . import compat
from .disc_mesh import MeshError
from .discretisation import Discretisation
from .pairs import PAIRS, get_pair

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

#: the mesh parameter a sweep varies, and its default values, per problem name
SWEEPS = {"membrane": ("N", (4, 8, 16, 32, 64)), "disc": ("level", (1, 2, 3))}


class InspectError(RuntimeError):
    """The measurement cannot be made (e.g. B rank deficient beyond the dense path's size)."""


# ---------------------------------------------------------------------------- gathering to rank 0
def _gather_csr(A, comm):
    """The distributed PETSc matrix A as a SciPy CSR matrix (global numbering) on rank 0, None elsewhere."""
    import scipy.sparse as sp
    r0, r1 = A.getOwnershipRange()
    indptr, indices, data = A.getValuesCSR()
    rows = np.repeat(np.arange(r0, r1, dtype=np.int64), np.diff(indptr))
    parts = comm.gather((rows, np.asarray(indices, dtype=np.int64), np.asarray(data, dtype=float)), root=0)
    if comm.rank != 0:
        return None
    rows, cols, vals = (np.concatenate(x) for x in zip(*parts))
    M = sp.csr_matrix((vals, (rows, cols)), shape=A.getSize())
    M.eliminate_zeros()
    return M


def _gather_global(local, offset, comm):
    """Owned local indices + this rank's global offset, gathered and sorted on rank 0 (None elsewhere)."""
    parts = comm.gather(np.asarray(local, dtype=np.int64) + offset, root=0)
    return np.sort(np.concatenate(parts)) if comm.rank == 0 else None


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


# ------------------------------------------------------------------------------ linear algebra
def measure(B, C, cidx, tol=TOL, dense_max=DENSE_MAX):
    """Condition (7) for B (N_H x N_W), C (N_H x N_H, SPD) and constrained columns ``cidx``.

    Pure SciPy/NumPy (no MPI): the numbers of :func:`inspect`. Returns a dict (see :func:`inspect`).
    """
    import scipy.sparse as sp
    B = sp.csr_matrix(B)
    nH, nW = B.shape
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
    Ng, dimF = len(cidx), nW - rank
    zeros = None                                       # number of zero eigenvalues of G P_F G^T, if known
    if Ng == 0:
        beta = None                                    # inf over an empty set: (7) holds vacuously
    elif dimF < Ng:
        beta = 0.0                                     # rank(G P_F G^T) <= dim F < N_g
        zeros = Ng - dimF if dimF == 0 else None
    else:
        sv = sl.svdvals(Z[cidx])                       # sigma(Z_c) = sqrt(eigenvalues of G P_F G^T)
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
    Ng = len(cidx)
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
        # P_F = I - B^T (B B^T)^-1 B, so S = G P_F G^T = I - Y^T (B B^T)^-1 Y, Y = B G^T
        Y = B[:, cidx].tocsc()
        if Ng <= dense_max:
            S = np.eye(Ng) - Y.T @ lu.solve(Y.toarray())
            lams = np.linalg.eigvalsh(0.5 * (S + S.T))
            lam, zeros = float(lams[0]), int(np.sum(lams <= tol ** 2))
            method += "S = G P_F G^T formed densely (LAPACK eigvalsh)"
        else:
            S = sla.LinearOperator((Ng, Ng), matvec=lambda q: q - Y.T @ lu.solve(Y @ q), dtype=float)
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
def inspect(problem, pair, tol=TOL, dense_max=DENSE_MAX):
    """Condition (7) for ``problem`` discretised with ``pair`` (a name or a Pair); the same dict on every rank.

    Keys: dim_W (W^h, Dirichlet dofs removed), dim_W_total, n_dirichlet, dim_H, N_g, rank_B, dim_ker_B,
    B_surjective, B_injective, rank_M, M_singular, count_condition (dim H <= dim W - N_g),
    kernel_condition (dim Ker(B) >= N_g), beta (None if N_g = 0), method, tolerance, verdict, reason, h.
    """
    pair = get_pair(pair) if isinstance(pair, str) else pair
    disc = Discretisation(problem, pair)
    comm = disc.comm
    h = cell_diameter(problem.mesh)
    B, C, cidx, n_dir = operators(disc)
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
                  dim_W_total=result["dim_W"] + n_dir, ranks=comm.size)
    return result


def sweep(make_problem, values, pairs, tol=TOL, dense_max=DENSE_MAX, progress=None):
    """inspect() for each mesh ``make_problem(value)`` and each pair: a list of result dicts."""
    rows = []
    for v in values:
        for pair in pairs:
            r = inspect(make_problem(v), pair, tol=tol, dense_max=dense_max)
            r["sweep_value"] = v
            rows.append(r)
            if progress:
                progress(r)
    return rows


# ------------------------------------------------------------------------------------- output
def _fmt_beta(b):
    return "inf" if b is None else f"{b:.6g}"


def report(r):
    """A human-readable block for one result."""
    names = {"N": "N", "level": "level", "h": "mesh size parameter", "diagonal": "diagonal", "mesh_file": "mesh"}
    par = ", ".join(f"{names[k]} = {v}" for k, v in r["parameters"].items() if k in names and v is not None)
    lines = [
        f"{r['problem']} ({par}; largest cell diameter {r['h']:.4g}), pair {r['pair']}, {r['ranks']} rank(s)",
        f"  dim W^h = {r['dim_W']} (Dirichlet dofs removed: {r['n_dirichlet']}), dim H^h = {r['dim_H']}, "
        f"N_g = {r['N_g']}, dim Ker(B) = {r['dim_ker_B']}",
        f"  count condition dim H^h <= dim W^h - N_g: {r['dim_H']} <= {r['dim_W'] - r['N_g']}: "
        f"{'yes' if r['count_condition'] else 'NO'}; dim Ker(B) >= N_g: {'yes' if r['kernel_condition'] else 'NO'}",
        f"  B: rank {r['rank_B']} of {r['dim_H']} rows: {'surjective' if r['B_surjective'] else 'NOT surjective'} "
        f"(Remark 1: {'every V0 admissible' if r['B_surjective'] else 'V0 must lie in Im(C^-1 B), eq. (6)'})"
        f"; sigma_min/sigma_max = {r['sigma_ratio_B']:.3g}",
        f"  M = B^T C^-1 B: rank {r['rank_M']} of {r['dim_W']}, {'singular' if r['M_singular'] else 'invertible'}"
        f" [{r['rank_M_method']}]",
        f"  beta (condition (7), Euclidean norms of coefficient vectors) = {_fmt_beta(r['beta'])}",
        f"  method: {r['method']} ({r['seconds']:.2f} s)",
        f"  verdict: {r['verdict'].upper()} (tolerance beta > {r['tolerance']:.1e}): {r['reason']}",
        f"  the paper: {r['paper']}",
    ]
    return "\n".join(lines)


SWEEP_HEADER = (f"{'pair':8s} {'param':>6s} {'h':>9s} {'dim W':>7s} {'dim H':>7s} {'N_g':>6s} {'dim Ker B':>9s} "
                f"{'beta':>10s} {'method':>9s}  verdict")


def sweep_line(r):
    """One line of the ``--sweep`` table for a result row."""
    return (f"{r['pair']:8s} {str(r['sweep_value']):>6s} {r['h']:9.4g} {r['dim_W']:7d} {r['dim_H']:7d} {r['N_g']:6d} "
            f"{r['dim_ker_B']:9d} {_fmt_beta(r['beta']):>10s} {r['method_short']:>9s}  {r['verdict']}")


def plot_sweep(rows, path, title=""):
    """Log-log beta against h, one curve per pair; beta <= tol is drawn as crosses on the tolerance line
    (with the names of the pairs concerned)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    tol = r_tol(rows)
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ill, ill_h = [], set()
    for k, name in enumerate(dict.fromkeys(r["pair"] for r in rows)):
        pts = sorted((r["h"], r["beta"]) for r in rows if r["pair"] == name and r["beta"] is not None)
        good = [(h, b) for h, b in pts if b > tol]
        if good:
            ax.loglog(*zip(*good), "o-", color=f"C{k}", label=name)
        if len(good) < len(pts):
            ill.append(name)
            ill_h.update(h for h, b in pts if b <= tol)
    if ill:      # pairs with beta <= tol all sit on the tolerance line: one marker for them all
        ax.loglog(sorted(ill_h), [tol] * len(ill_h), "kx", ms=9, mew=2,
                  label=r"$\beta \leq$ tol (ill-posed): " + ", ".join(ill))
    ax.axhline(tol, color="grey", ls="--", lw=0.8, label=f"tolerance {tol:.1e}")
    ax.set_xlabel("h (largest cell diameter)")
    ax.set_ylabel(r"$\beta$ of condition (7)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def r_tol(rows):
    """The verdict tolerance on beta used for ``rows`` (the default when there are none)."""
    return rows[0]["tolerance"] if rows else TOL


# ----------------------------------------------------------------------------------- command line
def _problems():
    """The problem modules: the run commands' registry, plus the disc if its module exists."""
    from .cli import PROBLEMS
    problems = dict(PROBLEMS)
    if "disc" not in problems:
        try:
            from . import disc
            if all(hasattr(disc, a) for a in ("add_arguments", "problem_from_args")):
                problems["disc"] = disc
        except ImportError:
            pass
    return problems


def _int_list(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1 (got {v})")
    return v


def _nonneg_float(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative finite number (got {text})")
    return v


def build_parser(problem, problems):
    """The ``inspect`` parser, with the options of ``problem`` (one of ``problems``)."""
    from .cli import _Parser
    p = _Parser(prog="python -m sdm_dolfinx inspect",
                description="Measure the inf-sup condition (7) of Renard (2010) for a problem, a pair and a mesh: "
                            "dimensions, Ker(B), rank of M = B^T C^-1 B, beta and a verdict.",
                epilog="Only the problem options that change the mesh or the constraint set (the membrane's --N, "
                       "--diagonal, --no-obstacle; the disc's --level, --h, --radius, --contact-zone, --no-contact) "
                       "change the result; the others are accepted for symmetry with the run commands.")
    p.add_argument("--problem", choices=sorted(problems), default="membrane", help="the problem (default membrane)")
    default_pair = getattr(problems.get(problem), "DEFAULTS", {}).get("pair", "P1+/P0")
    p.add_argument("--pair", nargs="+", default=[default_pair], metavar="PAIR",
                   help=f"one or more pairs, or 'all': {', '.join(PAIRS)} (default: the problem's, "
                        f"{default_pair} for {problem})")
    param, default_values = SWEEPS.get(problem, ("?", ()))
    p.add_argument("--sweep", nargs="*", type=_int_list, default=None, metavar="V",
                   help=f"run a sequence of meshes: values of --{param} (default {' '.join(map(str, default_values))})"
                        " and print beta against h")
    p.add_argument("--json", type=Path, default=None, metavar="FILE", help="write the results as JSON")
    p.add_argument("--png", type=Path, default=None, metavar="FILE",
                   help="with --sweep: the beta-h plot (default output/inspect/<problem>-beta.png)")
    p.add_argument("--tol", type=_nonneg_float, default=TOL,
                   help=f"beta <= tol counts as 0 (default 100 sqrt(eps) = {TOL:.2e})")
    p.add_argument("--dense-max", type=int, default=DENSE_MAX, metavar="N",
                   help=f"dense SVD up to dim W^h = N, iterative beyond (default {DENSE_MAX})")
    problems[problem].add_arguments(p)
    return p


def _check_writable(path, what):
    from .cli import UsageError
    if path.exists() and path.is_dir():
        raise UsageError(f"{what} {path} is a folder")
    d = path.parent
    while not d.exists():
        d = d.parent
    if not os.access(d, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write {what} {path} ({d} is not writable)")


def _parse(argv, problems):
    from .cli import UsageError
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--problem", default="membrane")
    known, _ = pre.parse_known_args(argv)
    if known.problem not in problems:
        raise UsageError(f"argument --problem: invalid choice: {known.problem!r} (choose from "
                         f"{', '.join(sorted(problems))})")
    parser = build_parser(known.problem, problems)
    args = parser.parse_args(argv)
    mod = problems[args.problem]
    errors = list(mod.check_arguments(args)) if hasattr(mod, "check_arguments") else []
    pairs = list(PAIRS) if args.pair == ["all"] else args.pair
    bad = [q for q in pairs if q not in PAIRS]
    if bad:
        errors.append(f"unknown pair {bad[0]!r}; choose from {', '.join(PAIRS)} or all")
    args.pair = list(dict.fromkeys(pairs))
    if args.dense_max < 0:
        errors.append(f"--dense-max must be >= 0 (got {args.dense_max})")
    if args.sweep is not None:
        if args.problem not in SWEEPS or not hasattr(args, SWEEPS[args.problem][0]):
            errors.append(f"--sweep is not available for problem {args.problem}")
        elif not args.sweep:
            args.sweep = list(SWEEPS[args.problem][1])
        if args.problem == "disc" and (getattr(args, "h", None) is not None or getattr(args, "mesh", None)):
            errors.append("--sweep runs the named --level meshes: drop --h/--mesh (or inspect one mesh at a time)")
    elif args.png is not None:
        errors.append("--png needs --sweep")
    if errors:
        raise UsageError("; ".join(errors))
    if args.json is not None:
        _check_writable(args.json, "--json")
    if args.sweep is not None:
        args.png = args.png or Path("output") / "inspect" / f"{args.problem}-beta.png"
        _check_writable(args.png, "--png")
    return args, mod


def main(argv=None):
    """``python -m sdm_dolfinx inspect ...``: returns the exit status (0, 1 failed measurement, 2 bad input)."""
    from .cli import UsageError, report_usage_error
    comm = MPI.COMM_WORLD
    argv = sys.argv[1:] if argv is None else list(argv)
    prog = "python -m sdm_dolfinx inspect"
    problems = _problems()
    try:
        if argv and argv[0] in ("-h", "--help") or "-h" in argv or "--help" in argv:
            pre = argparse.ArgumentParser(add_help=False)
            pre.add_argument("--problem", default="membrane")
            name = pre.parse_known_args(argv)[0].problem
            if comm.rank == 0:
                build_parser(name if name in problems else "membrane", problems).print_help()
            return 0
        args, mod = _parse(argv, problems)
    except UsageError as e:
        return report_usage_error(prog, e, comm)

    def say(text):
        if comm.rank == 0:
            print(text, flush=True)

    def make_problem(value=None):
        if value is not None:
            setattr(args, SWEEPS[args.problem][0], value)
            if args.problem == "disc" and hasattr(args, "h"):
                args.h = None             # the level sets the mesh size
        return mod.problem_from_args(args, comm)

    try:
        if args.sweep is None:
            rows = []
            problem = make_problem()
            for pair in args.pair:
                r = inspect(problem, pair, tol=args.tol, dense_max=args.dense_max)
                rows.append(r)
                say(report(r))
        else:
            param = SWEEPS[args.problem][0]
            say(f"sweep of {args.problem} over --{param} = {' '.join(map(str, args.sweep))} on {comm.size} rank(s); "
                f"beta of condition (7), tolerance {args.tol:.1e}")
            say(SWEEP_HEADER.replace("param", param))
            rows = sweep(make_problem, args.sweep, args.pair, tol=args.tol, dense_max=args.dense_max,
                         progress=lambda r: say(sweep_line(r)))
    except InspectError as e:
        if comm.rank == 0:
            print(f"{prog}: error: {e}", file=sys.stderr, flush=True)
        return 1
    except MeshError as e:              # a --mesh file that cannot be used: bad input
        if comm.rank == 0:
            print(f"{prog}: error: {e}", file=sys.stderr, flush=True)
        return 2
    if comm.rank == 0:
        if args.sweep is not None:
            args.png.parent.mkdir(parents=True, exist_ok=True)
            plot_sweep(rows, args.png, title=f"{args.problem}: inf-sup constant of condition (7)")
            print(f"wrote {args.png}", flush=True)
        if args.json is not None:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            doc = {"command": " ".join(["python -m sdm_dolfinx inspect"] + argv), "ranks": comm.size,
                   "tolerance": args.tol, "dense_max": args.dense_max, "versions": compat.versions(),
                   "results": rows}
            args.json.write_text(json.dumps(doc, indent=1, default=_json_default) + "\n")
            print(f"wrote {args.json}", flush=True)
    return 0


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, (np.bool_,)):
        return bool(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")
