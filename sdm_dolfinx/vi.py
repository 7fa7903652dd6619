"""Bound-constrained LCP solvers for one time step.

Each step of every scheme is the variational inequality (paper, after eq. (14))

    x_c >= lb,   lam = (K x - b)_c >= 0,   lam . (x_c - lb) = 0,   (K x - b)_i = 0 off c,

with K a constant symmetric matrix (SPD in the M formulation, a symmetric saddle point in
the (U, V) block formulation) whose Dirichlet rows are identity rows.

* :class:`SemismoothNewton` — the default: a primal-dual active set method, i.e. the
  semi-smooth Newton method on lam = max(0, lam - r (x_c - lb)) (Alart–Curnier, the
  paper's own solver). Its linear systems are K restricted to the inactive set, solved by
  one of :data:`LINEAR_STRATEGIES` (default ``auto``: one factorisation of K per run and
  the active set by a small dense Schur complement, or CG + AMG when there are many
  constraints; measurements in ``bench/README.md``). It runs as a PETSc SNES of type
  python (prefix ``sdm_``), so SNES monitors, options and converged reasons apply.
* :class:`SnesVI` — PETSc SNES ``vinewtonrsls`` (or ``vinewtonssls``) for comparison.

Both raise :class:`VIError` (with the PETSc / active-set reason) when they fail.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from . import compat

#: linear strategies of the semi-smooth Newton (see :class:`SemismoothNewton`)
LINEAR_STRATEGIES = ("auto", "schur", "cg-factor", "lu", "amg", "cg-amg")

#: ``auto`` takes ``schur`` up to this many constrained dofs, ``amg`` beyond: many
#: constraints (the membrane, N_g ~ N^2) mean active sets of thousands in the impact phase,
#: where CG + BoomerAMG scales best (bench/README.md)
SCHUR_MAX_CONSTRAINTS = 10000

#: ``schur`` solves a Newton system by the dense Schur complement while |active| is at most
#: this and at most SCHUR_MAX_COLUMNS columns are cached; otherwise by CG (GMRES) on the
#: inactive set preconditioned by the same factorisation (``cg-factor``)
SCHUR_MAX_ACTIVE = 100
SCHUR_MAX_COLUMNS = 1000

#: full cached columns K^-1 e_i are kept while they take less than this per rank (bytes);
#: beyond, each step ends with one more solve instead of a product with the columns
SCHUR_COLUMN_MEMORY = 2 * 1024 ** 3


class VIError(RuntimeError):
    """A step's variational inequality was not solved."""


class _options:
    """Context: extra PETSc options under ``prefix`` for the setFromOptions calls inside it.

    The defaults are set on the objects themselves, so that they never leak into the global
    options database and from one solver to the next; options given on the command line
    (``-sdm_...``) are in the database and override them.
    """

    def __init__(self, prefix, options, force=False):
        self.prefix, self.options, self.force = prefix, dict(options or {}), force
        self.added, self.saved = [], {}

    def __enter__(self):
        opts = PETSc.Options()
        for k, v in self.options.items():
            key = self.prefix + k
            if opts.hasName(key):
                if not self.force:
                    continue
                self.saved[key] = opts.getString(key)      # overridden for the context only
            else:
                self.added.append(key)
            opts.setValue(key, v)
        return self

    def __exit__(self, *exc):
        opts = PETSc.Options()
        for key in self.added:
            opts.delValue(key)
        for key, v in self.saved.items():
            opts.setValue(key, v)


def factor_package(comm, spd):
    """The sparse direct solver for one factorisation on ``comm`` (of one process's copy when
    the factorisation is redundant, see :class:`Factorisation`).

    One rank, SPD: CHOLMOD (supernodal Cholesky), measured 8x faster to factorise and
    50-100x faster to solve with than MUMPS on the membrane's step matrix (MUMPS's solve
    phase costs ~1 us per node of its elimination tree, and PORD leaves ~one node per
    unknown). Otherwise MUMPS (LDL^T for symmetric indefinite, distributed).
    """
    return "cholmod" if comm.size == 1 and spd else "mumps"


#: MUMPS's ICNTL(14): the percentage by which its work space exceeds the analysis's estimate.
#: MUMPS's default 20 % is not always enough on several ranks: on dolfinx 0.9 / PETSc 3.22
#: with 2 ranks the membrane P2/P1 factorisation failed in about 1 run in 3 with INFOG(1) = -9
#: (work array too small by a few dozen entries). :func:`factorise` starts from this value
#: and doubles it on -8/-9 failures.
MUMPS_ICNTL14 = 50


def _mumps_margins(prefix, retries=4):
    """The successive attempts of a MUMPS factorisation: (attempt, ICNTL(14), options context).

    ICNTL(14) starts from ``-<prefix>mat_mumps_icntl_14`` or :data:`MUMPS_ICNTL14` and doubles
    at each retry; a retry overrides even a value given on the command line.
    """
    pct = PETSc.Options().getInt(prefix + "mat_mumps_icntl_14", MUMPS_ICNTL14)
    for attempt in range(retries + 1):
        yield attempt, pct, _options(prefix, {"mat_mumps_icntl_14": str(pct)}, force=attempt > 0)
        pct *= 2


def factorise(M, comm, prefix, kind="cholesky", package="mumps", agree=None, retries=4):
    """A ``preonly`` KSP on ``comm`` holding a factorisation of M (set up: the factorisation
    is done).

    ``-<prefix>pc_factor_mat_solver_type`` and the other options under ``prefix`` override
    ``kind`` and ``package``. A MUMPS factorisation that runs out of work space (INFOG(1) =
    -8 or -9) is redone with twice the margin ICNTL(14) (:func:`_mumps_margins`), up to
    ``retries`` times; any other failure raises :class:`VIError` naming MUMPS's error code.
    ``agree``: the mpi4py communicator whose ranks retry or fail together (default: comm's).
    """
    if agree is None:
        agree = comm.tompi4py() if hasattr(comm, "tompi4py") else comm
    for attempt, pct, margin in _mumps_margins(prefix, retries):
        ksp = PETSc.KSP().create(comm)
        ksp.setOptionsPrefix(prefix)
        ksp.setOperators(M)
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType(kind)
        pc.setFactorSolverType(package)
        with margin:
            ksp.setFromOptions()
            ksp.setUp()
        reason = compat.pc_failed_reason(pc)
        infog = pc.getFactorMatrix().getMumpsInfog(1) if pc.getFactorSolverType() == "mumps" else 0
        worst = agree.allreduce(min(infog, 0), op=MPI.MIN)
        failed = agree.allreduce(reason != 0 or infog < 0, op=MPI.LOR)
        if not failed:
            return ksp
        ksp.destroy()
        if worst in (-8, -9) and attempt < retries:
            continue
        what = f"MUMPS INFOG(1) = {worst}, ICNTL(14) = {pct}" if worst else f"PC failed reason {reason}"
        raise VIError(f"the factorisation of the {M.getSize()[0]}-row step matrix failed ({what}); "
                      f"see the MUMPS user guide, or choose --linear amg")
    raise AssertionError("unreachable")


def augmented_matrix(A, B, c_lumped, alpha, ddofs):
    """[A, alpha B^T; alpha B, -D] with D = diag(c_lumped), Dirichlet dofs of A eliminated.

    Its Schur complement on the first block is K = A + alpha^2 B^T D^-1 B = alpha^2 M + A,
    the step matrix of the M formulation, so ``K x = r`` is ``aug [x; y] = [r; 0]``. For
    P2/P1, M couples every P2 dof with its P1 vertex patches' neighbours (46 nonzeros per
    row and component against A's 11): ``aug`` has less than half K's nonzeros and its
    factor a fraction of K's fill. Rows owned by a rank: its rows of K, then of D.
    """
    comm = A.getComm()
    rows = (A.getOwnershipRange()[0] + np.asarray(ddofs, dtype=np.int32)).astype(np.int32)
    A0 = A.copy()
    A0.zeroRowsColumns(rows, 1.0)
    B0 = B.copy()
    keep = B0.createVecRight()
    keep.set(1.0)
    keep.array[np.asarray(ddofs, dtype=np.int32)] = 0.0
    B0.diagonalScale(R=keep)                  # Dirichlet columns of B removed
    B0.scale(alpha)
    Bt = B0.transpose(PETSc.Mat())
    D = PETSc.Mat().createAIJ((B.getSizes()[0], B.getSizes()[0]), nnz=(1, 0), comm=comm)
    D.setUp()
    d = c_lumped.copy()
    d.scale(-1.0)
    D.setDiagonal(d)
    D.assemble()
    nest = PETSc.Mat().createNest([[A0, Bt], [B0, D]], comm=comm)
    aug = nest.convert("aij", PETSc.Mat())
    aug.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    for m in (nest, A0, B0, Bt, D, keep, d):
        m.destroy()
    return aug


#: :func:`sparse_factor_matrix` only from this many rows of K: below, factorising K is cheap
#: anyway, and K's Cholesky factorisation propagates less round-off (1 and 2 ranks agree to
#: 1e-12 over the 300 steps of the membrane P2/P1 test, 2e-10 through the augmented matrix)
AUG_MIN_ROWS = 20_000


def sparse_factor_matrix(K, A, B, c_lumped, alpha, ddofs, ratio=0.6):
    """:func:`augmented_matrix` when K has at least :data:`AUG_MIN_ROWS` rows and the
    augmented matrix less than ``ratio`` times K's nonzeros, else None."""
    if K.getSize()[0] < AUG_MIN_ROWS:
        return None
    aug = augmented_matrix(A, B, c_lumped, alpha, ddofs)
    comm = K.getComm().tompi4py()
    local = PETSc.Mat.InfoType.LOCAL
    nz_aug = comm.allreduce(aug.getInfo(local)["nz_used"], op=MPI.SUM)
    nz_K = comm.allreduce(K.getInfo(local)["nz_used"], op=MPI.SUM)
    if nz_aug < ratio * nz_K:
        return aug
    aug.destroy()
    return None


#: on several ranks a factorised matrix with at most this many rows is gathered on every
#: rank and factorised there (``-sdm_factor_redundant 0|1`` overrides); larger ones are
#: factorised by MUMPS distributed over the ranks. Small systems are latency-bound: MUMPS's
#: distributed solve exchanges messages at every node of the top of its elimination tree,
#: while a redundant solve needs one allgather of the right-hand side and the columns of
#: K^-1 need no communication at all. Measured on a quiet 2-core machine (solve times,
#: 1 rank / 2 ranks redundant / 2 ranks distributed): membrane P1+/P0 N = 80 (19k rows,
#: CHOLMOD) 0.31 / 1.39 / 12.7 ms; disc level 4 (57k rows of the augmented matrix)
#: 28 / 36 / 21 ms; level 5 (158k rows) 79-87 / 79 / 53-62 ms. On an oversubscribed machine the
#: distributed solve is much worse (2 ranks 100x slower than 1 on a 1600-dof membrane at
#: load 9: each wait yields the core for a scheduler slice); ``-sdm_factor_redundant 1``.
REDUNDANT_MAX_ROWS = 50_000


class Factorisation:
    """One factorisation for the whole run: x = K^-1 r, for one or many right-hand sides.

    Args:
        K: the step matrix.
        spd: K is SPD (Cholesky) or only symmetric (LDL^T / LU).
        prefix: PETSc options prefix (``-<prefix>pc_factor_mat_solver_type`` overrides
            :func:`factor_package`; ``-<prefix>redundant 0|1`` see :data:`REDUNDANT_MAX_ROWS`).
        aug: optional sparser matrix whose leading block's Schur complement is K (see
            :func:`augmented_matrix`); it is factorised instead of K.
    """

    def __init__(self, K, spd, prefix, aug=None):
        self.K, self.aug, self.comm = K, aug, K.getComm().tompi4py()
        self.n = K.getLocalSize()[0]
        M = aug if aug is not None else K
        Ng = M.getSize()[0]
        opts = PETSc.Options()
        self.redundant = self.comm.size > 1 and opts.getBool(prefix + "redundant", Ng <= REDUNDANT_MAX_ROWS)
        if self.redundant:
            # every rank holds M whole (global numbering); K's rows of rank r are M's rows
            # a0_r .. a0_r + n_r
            full = PETSc.IS().createStride(Ng, 0, 1, comm=PETSc.COMM_SELF)
            M = M.createSubMatrices(full)[0]
            full.destroy()
            a0 = (aug if aug is not None else K).getOwnershipRange()[0]
            k0 = K.getOwnershipRange()[0]
            ranges = self.comm.allgather((a0, k0, self.n))
            self._counts = [n for _, _, n in ranges]
            self._pos = np.concatenate([a + np.arange(n) for a, _, n in ranges]).astype(np.int64)
            self._mine = a0 + np.arange(self.n)
            self._kranges = ranges
            comm = PETSc.COMM_SELF
        else:
            comm = self.comm
        size1 = self.redundant or self.comm.size == 1
        if aug is not None:
            M.setOption(PETSc.Mat.Option.SYMMETRIC, True)
            kind, package = "cholesky", "mumps"     # LDL^T of the symmetric indefinite matrix
        else:
            kind, package = ("cholesky" if spd else "lu"), ("cholmod" if size1 and spd else "mumps")
        ksp = factorise(M, comm, prefix, kind, package, agree=self.comm)
        self.ksp, self.M = ksp, M
        self.package = ksp.getPC().getFactorSolverType()
        self.F = ksp.getPC().getFactorMatrix()
        self.ra, self.xa = M.createVecLeft(), M.createVecRight()
        self.solves = 0

    def _gather(self, r_local):
        """The full right-hand side (M's global numbering) from every rank's K rows."""
        buf = np.empty(len(self._pos))
        self.comm.Allgatherv(np.ascontiguousarray(r_local), [buf, self._counts])
        full = np.zeros(self.M.getSize()[0])
        full[self._pos] = buf
        return full

    def solve(self, r, x):
        """x = K^-1 r (PETSc vectors of K's layout)."""
        self.solves += 1
        if self.redundant:
            self.ra.array[:] = self._gather(r.array_r)
            self.ksp.solve(self.ra, self.xa)
            x.array[:] = self.xa.array_r[self._mine]
            return
        if self.aug is None:
            self.ksp.solve(r, x)
            return
        n = self.n
        self.ra.set(0.0)
        self.ra.array[:n] = r.array_r
        self.ksp.solve(self.ra, self.xa)
        x.array[:] = self.xa.array_r[:n]

    def _rows_of(self, g):
        """(row of M on this process's M, local row of K if owned here or -1) for K-global g."""
        if not self.redundant:
            r0K = self.K.getOwnershipRange()[0]
            own = (g >= r0K) & (g < r0K + self.n)
            return np.where(own, g - r0K, -1), own
        rows = np.empty(len(g), dtype=np.int64)
        for a0, k0, n in self._kranges:
            sel = (g >= k0) & (g < k0 + n)
            rows[sel] = a0 + g[sel] - k0
        return rows, np.ones(len(g), dtype=bool)

    def solve_columns(self, gcols, chunk=64):
        """Local rows (n_local x len(gcols)) of K^-1 e_g for the global indices ``gcols``.

        Collective; every rank passes the same list. Solved ``chunk`` at a time with one
        multiple-right-hand-side solve (MatMatSolve); redundantly without communication
        when the factorisation is redundant.
        """
        gcols = np.asarray(gcols, dtype=np.int64)
        out = np.empty((self.n, len(gcols)))
        nl, Ng = self.M.getLocalSize()[0], self.M.getSize()[0]
        comm = self.M.getComm()
        for s in range(0, len(gcols), chunk):
            g = gcols[s:s + chunk]
            k = len(g)
            Bm = PETSc.Mat().createDense([(nl, Ng), (None, k)], comm=comm)
            Bm.setUp()
            Xm = PETSc.Mat().createDense([(nl, Ng), (None, k)], comm=comm)
            Xm.setUp()
            b = Bm.getDenseArray()
            b[:] = 0.0
            rows, own = self._rows_of(g)
            mine = np.flatnonzero(own)
            b[rows[mine], mine] = 1.0        # K-space rows come first in aug's local rows too
            Bm.assemble()
            Xm.assemble()
            self.F.matSolve(Bm, Xm)
            X = Xm.getDenseArray()
            out[:, s:s + k] = X[self._mine, :] if self.redundant else X[:self.n, :]
            Bm.destroy()
            Xm.destroy()
            self.solves += k
        return out

    def destroy(self):
        self.ksp.destroy()
        self.ra.destroy()
        self.xa.destroy()
        if self.redundant:
            self.M.destroy()


class _ReducedOperator:
    """y = K_A x: K with the active rows and columns replaced by the identity."""

    def __init__(self, K, active_mask):
        self.K, self.mask = K, active_mask
        self.tmp = K.createVecRight()

    def mult(self, mat, x, y):
        xa = x.getArray(readonly=True)
        self.tmp.array[:] = xa
        self.tmp.array[self.mask] = 0.0
        self.K.mult(self.tmp, y)
        y.array[self.mask] = xa[self.mask]


class _ReducedPC:
    """z = P restricted to the inactive set (identity on the active set), P ~ K^-1.

    With P = K^-1 (one factorisation) this differs from (K_A)^-1 by a term of rank
    |active|, so Krylov converges in at most |active| + 1 iterations; with P one AMG cycle
    on K, the AMG set-up is done once per run.
    """

    def __init__(self, apply_P, active_mask, K):
        self.apply_P, self.mask = apply_P, active_mask
        self.tmp, self.z = K.createVecRight(), K.createVecLeft()

    def apply(self, pc, r, z):
        ra = r.getArray(readonly=True)
        self.tmp.array[:] = ra
        self.tmp.array[self.mask] = 0.0
        self.apply_P(self.tmp, self.z)
        z.array[:] = self.z.array_r
        z.array[self.mask] = ra[self.mask]


def choose_strategy(num_constraints, spd):
    """What ``linear="auto"`` means: ``schur``, or ``amg`` for many constraints (SPD only)."""
    return "schur" if num_constraints <= SCHUR_MAX_CONSTRAINTS or not spd else "amg"


#: the VI solvers' own options (after the prefix): name -> (parse, valid, what is allowed);
#: :func:`_vi_tolerances` and the command line (``cli._petsc_overrides``) check them with these
VI_OPTIONS = {"vi_rtol": (float, lambda v: 0 < v < 1, "a number in (0, 1)"),
              "vi_max_it": (int, lambda v: v >= 1, "an integer >= 1"),
              "vi_monitor": (str, lambda v: v.lower() in ("", "1", "0", "true", "false", "yes", "no"),
                             "true or false (or no value)")}


def _vi_tolerances(prefix, rtol, max_it, options=None):
    """The step solver's own settings, overridable as PETSc options for either VI solver:
    ``-<prefix>vi_rtol`` (complementarity tolerance relative to max|b|),
    ``-<prefix>vi_max_it`` (iterations per step) and ``-<prefix>vi_monitor`` (one line per
    iteration on rank 0). The command line wins over ``options`` (keys without the
    prefix), which wins over the arguments."""
    opts = PETSc.Options()
    with _options(prefix, {k: v for k, v in (options or {}).items() if k.startswith("vi_")}):
        rtol = opts.getReal(prefix + "vi_rtol", rtol)
        max_it = opts.getInt(prefix + "vi_max_it", max_it)
        monitor = opts.getBool(prefix + "vi_monitor", False)
    for name, value in (("vi_rtol", rtol), ("vi_max_it", max_it)):
        _, valid, allowed = VI_OPTIONS[name]
        if not valid(value):
            raise VIError(f"-{prefix}{name}: {value!r} is not {allowed}")
    return rtol, max_it, monitor


class SemismoothNewton:
    """Primal-dual active set (semi-smooth Newton) solver for the step LCP.

    Args:
        K: the step matrix (PETSc Mat, Dirichlet rows = identity rows).
        cdofs: owned local indices of the constrained entries of x.
        lb: their lower bounds.
        symmetric_positive: K is SPD (M formulation) -> CG; otherwise GMRES.
        linear: how the linear systems on the inactive set are solved:

            * ``"schur"``: K is factorised once per run; a system with active set A is
              x = K^-1 b + Z mu, Z = K^-1 E_A (columns cached for the whole run), with mu
              from the small dense system (E_A^T Z) mu = lb_A - (K^-1 b)_A. Each step
              costs one solve with the factorisation (plus one per newly active
              constraint); the Newton iterations themselves are dense |A| x |A| work.
            * ``"cg-factor"``: K factorised once; CG (GMRES) on the inactive set
              preconditioned by that factorisation.
            * ``"lu"``: factorise the reduced matrix at every Newton iteration (baseline).
            * ``"amg"``: CG + BoomerAMG on the reduced matrix, set up at every iteration.
            * ``"cg-amg"``: CG on the inactive set preconditioned by one BoomerAMG set-up
              of K for the whole run (for sizes where a factorisation does not fit).
            * ``"auto"``: :func:`choose_strategy` (``schur`` unless there are many
              constrained dofs).
        prefix: PETSc options prefix (same on every rank); options under it override.
        options: default PETSc options (a dict, keys without the prefix).
        factor_matrix: optional sparser augmented matrix factorised instead of K (see
            :func:`augmented_matrix`).
        rtol: tolerance of the complementarity tests, relative to max|b|.
        max_it: Newton iterations before giving up.
    """

    def __init__(self, K, cdofs, lb, symmetric_positive=True, linear="auto", prefix="sdm_",
                 options=None, factor_matrix=None, rtol=1e-10, max_it=500):
        if linear not in LINEAR_STRATEGIES:
            raise ValueError(f"unknown linear strategy {linear!r}; choose one of {', '.join(LINEAR_STRATEGIES)}")
        self.K, self.comm = K, K.getComm().tompi4py()
        self.cdofs = np.asarray(cdofs, dtype=np.int32)
        self.lb = np.asarray(lb, dtype=PETSc.ScalarType)
        self.num_constraints = self.comm.allreduce(len(self.cdofs), op=MPI.SUM)
        if linear == "auto":
            linear = choose_strategy(self.num_constraints, symmetric_positive)
        self.spd, self.linear, self.prefix = symmetric_positive, linear, prefix
        self.factor_matrix = factor_matrix
        self.rtol, self.max_it, self.monitor = _vi_tolerances(prefix, rtol, max_it, options)
        self.mask = np.zeros(K.getLocalSize()[0], dtype=bool)     # active entries of x
        self.active = np.zeros(len(self.cdofs), dtype=bool)          # active constraints
        self.lam = np.zeros(len(self.cdofs))
        diag = K.getDiagonal()
        dsum = self.comm.allreduce(float(np.sum(diag.array[self.cdofs])), op=MPI.SUM)
        nc = self.num_constraints
        self.r = dsum / nc if nc else 1.0   # the Alart–Curnier parameter r (mean diagonal)
        self.total_linear_its = 0
        self.fac = None
        self._KA = self._KA_mask = None
        with _options(prefix, options):
            self._setup()
            self.snes = self._make_snes()
        self.max_it = self.snes.getTolerances()[3]       # -sdm_snes_max_it may change it

    def _make_snes(self):
        """The semi-smooth Newton as a PETSc SNES of type python (prefix ``sdm_``): SNES
        monitors (``-sdm_snes_monitor``: the Alart–Curnier residual of each iteration),
        ``-sdm_snes_converged_reason``, ``-sdm_snes_max_it``, ``-sdm_snes_view`` and the
        converged reason apply as for any SNES."""
        snes = PETSc.SNES().create(self.comm)
        snes.setOptionsPrefix(self.prefix)
        snes.setType("python")
        snes.setPythonContext(_SnesContext(self))
        self._F = self.K.createVecLeft()
        snes.setFunction(_lcp_residual(self.K), self._F)
        snes.setTolerances(max_it=self.max_it)
        ksp = snes.getKSP()             # not used: the iterations solve with self.ksp / self.fac
        ksp.setType("preonly")
        ksp.getPC().setType("none")
        snes.setFromOptions()
        return snes

    def _setup(self):
        K, n = self.K, self.K.getLocalSize()[0]
        N = K.getSize()[0]
        if self.linear in ("schur", "cg-factor"):
            self.fac = Factorisation(K, self.spd, self.prefix + "factor_", aug=self.factor_matrix)
        if self.linear == "schur":
            self._init_schur()
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOptionsPrefix(self.prefix)
        ksp.setTolerances(rtol=1e-12, atol=1e-50, max_it=5000)
        if self.linear in ("cg-factor", "cg-amg", "schur"):
            if self.linear in ("cg-factor", "schur"):
                apply_P = self.fac.solve
            else:
                ka = PETSc.KSP().create(self.comm)
                ka.setOptionsPrefix(self.prefix + "amg_")
                ka.setOperators(K)
                ka.setType("preonly")
                ka.getPC().setType("hypre")
                ka.getPC().setHYPREType("boomeramg")
                ka.setFromOptions()
                ka.setUp()
                self.ksp_amg = ka
                apply_P = ka.solve
            op = PETSc.Mat().createPython([(n, N), (n, N)], _ReducedOperator(K, self.mask), comm=self.comm)
            op.setUp()
            self.op = op
            ksp.setOperators(op)
            ksp.setType("cg" if self.spd else "gmres")
            if not self.spd:
                ksp.setGMRESRestart(300)
            pc = ksp.getPC()
            pc.setType("python")
            pc.setPythonContext(_ReducedPC(apply_P, self.mask, K))
        elif self.linear == "lu":
            ksp.setType("preonly")
            ksp.getPC().setType("cholesky" if self.spd else "lu")
            ksp.getPC().setFactorSolverType("mumps")
        else:
            ksp.setType("cg" if self.spd else "gmres")
            ksp.getPC().setType("hypre")
            ksp.getPC().setHYPREType("boomeramg")
        ksp.setFromOptions()
        self.ksp = ksp

    # ------------------------------------------------------------------ iterative / lu
    def _reduced_matrix(self):
        rows = self.K.getOwnershipRange()[0] + np.flatnonzero(self.mask).astype(np.int32)
        KA = self.K.copy()
        KA.zeroRowsColumns(rows, 1.0)
        return KA

    def _linear_solve(self, rhs, x):
        shell = self.linear in ("cg-factor", "cg-amg", "schur")
        if shell:
            self.op.assemble()
        elif self.linear == "lu" or self._KA is None or self.comm.allreduce(
                not np.array_equal(self.mask, self._KA_mask), op=MPI.LOR):
            # lu: refactorise at every iteration (the baseline); amg: set up again only when
            # the active set changed on some rank (never in the free phase)
            if self._KA is not None:
                self._KA.destroy()
            self._KA, self._KA_mask = self._reduced_matrix(), self.mask.copy()
            self.ksp.setOperators(self._KA)
        if self.linear == "lu":     # MUMPS reads its options at each factorisation
            for _, _, margin in _mumps_margins(self.prefix):   # as in factorise
                with margin:
                    self.ksp.solve(rhs, x)
                if self.ksp.getConvergedReason() != PETSc.KSP.ConvergedReason.DIVERGED_PCSETUP_FAILED:
                    break
                self.ksp.getPC().reset()
                self.ksp.setOperators(self._KA)
        else:
            self.ksp.solve(rhs, x)
        reason = self.ksp.getConvergedReason()
        self.total_linear_its += max(self.ksp.getIterationNumber(), 1)
        if reason <= 0:
            raise VIError(f"linear solve on the inactive set failed (KSP reason {reason}: "
                          f"{_ksp_reason_name(reason)})")

    def _newton_system(self, b, x, active, work):
        """Solve x_A = lb_A, (K x - b)_I = 0; return (x at the constraints, multipliers)."""
        c, lb = self.cdofs, self.lb
        rhs, res, xa = work
        self.mask[:] = False
        self.mask[c[active]] = True
        # the operator zeroes the active columns: move K_{:,A} lb_A to the right-hand side
        xa.set(0.0)
        xa.array[c[active]] = lb[active]
        self.K.mult(xa, rhs)
        rhs.aypx(-1.0, b)
        rhs.array[c[active]] = lb[active]
        x.array[c[active]] = lb[active]
        self._linear_solve(rhs, x)
        # multipliers lam = (K x - b) on the active set
        self.K.mult(x, res)
        res.axpy(-1.0, b)
        return x.array[c].copy(), res.array[c].copy()

    # ------------------------------------------------------------------ schur
    def _init_schur(self):
        self.gc = (self.K.getOwnershipRange()[0] + self.cdofs).astype(np.int64)   # global ids
        self._slot = {}                                   # global id -> column slot
        self._Zc = np.zeros((len(self.cdofs), 0))         # cached columns at the constraints
        self._Zf = np.zeros((self.K.getLocalSize()[0], 0))   # ... and in full (if they fit)
        self._full = True
        self._ncols = 0
        self._x0 = self.K.createVecRight()
        self._rhs = self.K.createVecLeft()

    def _ensure_columns(self, gids):
        """Compute and cache K^-1 e_g for the ids not cached yet (collective, same list)."""
        missing = [g for g in gids if g not in self._slot]
        if not missing:
            return
        cols = self.fac.solve_columns(missing)
        self.total_linear_its += len(missing)
        k = len(missing)
        need = self._ncols + k
        if need > self._Zc.shape[1]:
            cap = max(need, 2 * self._Zc.shape[1], 16)
            Zc = np.zeros((self._Zc.shape[0], cap))
            Zc[:, :self._ncols] = self._Zc[:, :self._ncols]
            self._Zc = Zc
            full_ok = self.comm.allreduce(self._Zf.shape[0] * cap * 8 <= SCHUR_COLUMN_MEMORY, op=MPI.LAND)
            if self._full and full_ok:
                Zf = np.zeros((self._Zf.shape[0], cap))
                Zf[:, :self._ncols] = self._Zf[:, :self._ncols]
                self._Zf = Zf
            else:
                self._full, self._Zf = False, None
        self._Zc[:, self._ncols:need] = cols[self.cdofs, :]
        if self._full:
            self._Zf[:, self._ncols:need] = cols
        for j, g in enumerate(missing):
            self._slot[g] = self._ncols + j
        self._ncols = need

    def _schur_system(self, active):
        """x_c and the multipliers for active set ``active`` from the cached columns.

        With x = x0 + Z mu (x0 = K^-1 b, Z = K^-1 E_A), K x - b = E_A mu: mu is the
        multiplier, and x_A = lb_A is the dense SPD system (Z_AA) mu = lb_A - x0_A (Z_AA is
        the constrained block of K^-1; of its Schur complement for the block formulation).
        """
        comm = self.comm
        la = self.gc[active]
        parts = comm.allgather(la)
        gA = np.concatenate(parts) if parts else la
        new = sum(1 for g in gA.tolist() if g not in self._slot)
        if len(gA) > SCHUR_MAX_ACTIVE or self._ncols + new > SCHUR_MAX_COLUMNS:
            return None                                    # too large: Krylov instead
        self._ensure_columns(gA.tolist())
        slots = np.array([self._slot[g] for g in gA.tolist()], dtype=np.int64)
        rows = np.flatnonzero(active)
        S_loc = self._Zc[np.ix_(rows, slots)]
        r_loc = self.lb[active] - self._x0c[active]
        S = np.vstack(comm.allgather(S_loc)) if len(gA) else np.zeros((0, 0))
        r = np.concatenate(comm.allgather(r_loc))
        mu = np.linalg.solve(S, r) if len(gA) else np.zeros(0)
        xc = self._x0c + self._Zc[:, slots] @ mu
        off = sum(len(p) for p in parts[:comm.rank])
        lam = np.zeros(len(self.cdofs))
        lam[rows] = mu[off:off + len(rows)]
        self._mu, self._slots, self._mu_local = mu, slots, mu[off:off + len(rows)]
        return xc, lam

    def _schur_finish(self, b, x, active):
        """The full x of the accepted active set."""
        c = self.cdofs
        if self._full:
            x.array[:] = self._x0.array_r + self._Zf[:, self._slots] @ self._mu
        else:           # one more solve: K x = b + E_A mu
            b.copy(self._rhs)
            self._rhs.array[c[active]] += self._mu_local
            self.fac.solve(self._rhs, x)
            self.total_linear_its += 1
        x.array[c[active]] = self.lb[active]

    # ------------------------------------------------------------------ Newton
    def solve(self, b, x):
        """Solve the LCP for right-hand side b; x holds the initial guess and the result.

        Runs :meth:`newton` through the SNES (see :meth:`_make_snes`).

        Returns:
            dict with ``its`` (Newton iterations) and ``n_active``.

        Raises:
            VIError: no convergence, or a failed linear solve (with the reason).
        """
        self._result = self._error = None
        self.snes.solve(b, x)
        if self._error is not None:
            raise self._error
        return self._result

    def newton(self, b, x, snes):
        """Solve the LCP for right-hand side b; x holds the initial guess and the result
        (called by the SNES of :meth:`_make_snes`, which ``snes`` is: it gets the
        iteration number, the residual norm and the monitor calls).

        Each iteration exchanges the infeasible constraints between the active and the
        inactive set (active with lam < 0: release; inactive with x < lb: add), which is the
        primal-dual active set / semi-smooth Newton step. For matrices that are not
        M-matrices (P2 vertex–edge coupling) full exchanges may cycle; as in Júdice & Pires'
        block principal pivoting, when the number of infeasibilities has not decreased for
        3 iterations only the infeasible constraint of largest global index is exchanged
        (Murty's rule), which terminates for any P-matrix (our Schur complement on the
        constrained dofs is SPD).

        Returns:
            dict with ``its`` (Newton iterations) and ``n_active``.
        """
        c, lb = self.cdofs, self.lb
        scale = max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        tol_lam = self.rtol * scale
        tol_x = tol_lam / self.r
        schur = self.linear == "schur"
        if schur:       # x0 = K^-1 b once per step; the iterations reuse it
            self.fac.solve(b, self._x0)
            self.total_linear_its += 1
            self._x0c = self._x0.array_r[c].copy()
        work = None
        active = self.active.copy()
        gidx = self.K.getOwnershipRange()[0] + c           # global indices, for Murty's rule
        best, patience = np.inf, 3
        for it in range(1, self.max_it + 1):
            # Newton step: x_A = lb_A, K_II x_I = b_I - K_IA lb_A
            by_schur = schur and self._schur_system(active)
            if by_schur:
                xc, lam = by_schur
            else:
                if work is None:
                    work = (b.duplicate(), b.duplicate(), b.duplicate())
                xc, lam = self._newton_system(b, x, active, work)
            lam = np.where(active, lam, 0.0)
            infeasible = np.where(active, lam < -tol_lam, xc < lb - tol_x)
            n_inf = self.comm.allreduce(int(np.count_nonzero(infeasible)), op=MPI.SUM)
            self.lam, self.active = lam, active
            # the Alart–Curnier residual |lam - max(0, lam - r (x - lb))|, for SNES monitors
            res = np.where(active, np.minimum(lam, 0.0), self.r * np.minimum(xc - lb, 0.0))
            fnorm = float(np.sqrt(self.comm.allreduce(float(res @ res), op=MPI.SUM)))
            snes.setIterationNumber(it)
            snes.setFunctionNorm(fnorm)
            snes.monitor(it, fnorm)
            if self.monitor:
                n_act = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
                if self.comm.rank == 0:
                    print(f"  {it:3d} semi-smooth Newton: {n_act} active, {n_inf} infeasible "
                          f"(tolerance {tol_lam:.3e})", flush=True)
            if n_inf == 0:
                if by_schur:
                    self._schur_finish(b, x, active)
                n_active = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
                return {"its": it, "n_active": n_active}
            if n_inf < best:
                best, patience = n_inf, 3
            elif patience > 0:
                patience -= 1
            else:                       # Murty: exchange one constraint only
                gmax = self.comm.allreduce(int(np.max(gidx[infeasible], initial=-1)), op=MPI.MAX)
                infeasible = gidx == gmax
            active = active ^ infeasible
        raise VIError(f"semi-smooth Newton did not converge in {self.max_it} iterations "
                      f"({n_inf} constraints still infeasible)")

    def destroy(self):
        self.snes.destroy()
        self.ksp.destroy()
        if self._KA is not None:
            self._KA.destroy()
        if self.linear in ("cg-factor", "cg-amg", "schur"):
            self.op.destroy()
        if self.linear == "cg-amg":
            self.ksp_amg.destroy()
        if self.fac is not None:
            self.fac.destroy()


def _lcp_residual(K):
    """SNES function callback F(x) = K x - b (b: the SNES right-hand side, applied by PETSc)."""
    def residual(snes, x, F):
        K.mult(x, F)
    return residual


class _SnesContext:
    """python-type SNES context: the semi-smooth Newton iterations of a
    :class:`SemismoothNewton`, with their converged reason."""

    def __init__(self, ssn):
        self.ssn = ssn

    def view(self, snes, viewer):
        ssn = self.ssn
        fac = "" if ssn.fac is None else (f", one {ssn.fac.package} factorisation per run"
                                          + (" (redundant: one per rank)" if ssn.fac.redundant else ""))
        viewer.printfASCII(f"    semi-smooth Newton (primal-dual active set) on {ssn.num_constraints} bounds: "
                           f"linear strategy {ssn.linear}{fac}, complementarity tolerance {ssn.rtol:g} x max|b|, "
                           f"Alart-Curnier r = {ssn.r:.6g}\n")

    def solve(self, snes, b, x):
        R = PETSc.SNES.ConvergedReason
        try:
            self.ssn._result = self.ssn.newton(b, x, snes)
            snes.setConvergedReason(R.CONVERGED_FNORM_ABS)
        except VIError as e:                 # raised again by SemismoothNewton.solve
            self.ssn._error = e
            snes.setConvergedReason(R.DIVERGED_MAX_IT if "did not converge" in str(e) else R.DIVERGED_LINEAR_SOLVE)


class SnesVI:
    """PETSc SNES ``vinewtonrsls`` on the step LCP (bounds via ``setVariableBounds``).

    Tolerances are relative to the right-hand side: an absolute 1e-12 stalls at round-off
    (STYLE pitfall). Known to cycle on P2/P1 at the first impact; kept for comparison.
    """

    def __init__(self, K, cdofs, lb, symmetric_positive=True, snes_type="vinewtonrsls", prefix="sdm_",
                 options=None, rtol=1e-10, max_it=60):
        self.K, self.comm = K, K.getComm().tompi4py()
        self.cdofs = np.asarray(cdofs, dtype=np.int32)
        self.lb = np.asarray(lb)
        rtol, max_it, monitor = _vi_tolerances(prefix, rtol, max_it, options)
        self.rtol, self.prefix = rtol, prefix
        self.lam = np.zeros(len(self.cdofs))
        self.total_linear_its = 0
        snes = PETSc.SNES().create(self.comm)
        snes.setOptionsPrefix(prefix)
        snes.setType(snes_type)
        snes.setTolerances(max_it=max_it)
        ksp = snes.getKSP()
        ksp.setType("preonly")
        ksp.getPC().setType("cholesky" if symmetric_positive else "lu")
        ksp.getPC().setFactorSolverType("mumps")
        self.F = K.createVecLeft()
        self._b = None
        snes.setFunction(self._residual, self.F)
        snes.setJacobian(self._jacobian, K, K)
        xl, xu = K.createVecRight(), K.createVecRight()
        xl.set(PETSc.NINFINITY)
        xu.set(PETSc.INFINITY)
        xl.array[self.cdofs] = self.lb
        self.xl, self.xu = xl, xu
        snes.setVariableBounds(xl, xu)
        # a piecewise-linear VI wants a full step (petsc4py 3.18 has no getLineSearch)
        defaults = {"snes_linesearch_type": "basic", **({"snes_monitor": ""} if monitor else {}), **(options or {})}
        with _options(prefix, defaults):
            snes.setFromOptions()
        self.snes = snes
        self.work = K.createVecRight()

    def _residual(self, snes, x, F):
        self.K.mult(x, F)
        F.axpy(-1.0, self._b)

    def _jacobian(self, snes, x, J, P):
        return None

    def solve(self, b, x):
        self._b = b
        scale = max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        self.snes.setTolerances(atol=self.rtol * scale, rtol=self.rtol, stol=0.0)
        x.copy(self.work)                  # SNES solves into its own work vector
        with _options(self.prefix, {"mat_mumps_icntl_14": str(MUMPS_ICNTL14)}):
            self.snes.solve(None, self.work)
        reason = self.snes.getConvergedReason()
        if reason <= 0:
            raise VIError(f"SNES {self.snes.getType()} diverged (reason {reason}: "
                          f"{_snes_reason_name(reason)})")
        self.work.copy(x)
        self._residual(None, x, self.F)
        gap = x.array[self.cdofs] - self.lb
        tol_x = self.rtol * max(1.0, float(np.max(np.abs(self.lb), initial=0.0)))
        active = gap <= tol_x
        self.lam = np.where(active, self.F.array[self.cdofs], 0.0)
        self.total_linear_its += self.snes.getLinearSolveIterations()
        n_active = self.comm.allreduce(int(np.count_nonzero(active)), op=MPI.SUM)
        return {"its": self.snes.getIterationNumber(), "n_active": n_active}

    def destroy(self):
        self.snes.destroy()


def _ksp_reason_name(reason):
    names = {v: k for k, v in vars(PETSc.KSP.ConvergedReason).items() if isinstance(v, int)}
    return names.get(reason, "unknown")


def _snes_reason_name(reason):
    names = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
    return names.get(reason, "unknown")


VI_SOLVERS = ("ssn", "vinewtonrsls", "vinewtonssls")


def make_vi_solver(name, K, cdofs, lb, symmetric_positive=True, linear="auto", options=None, factor_matrix=None):
    """Build the step solver ``name`` (one of :data:`VI_SOLVERS`).

    ``factor_matrix``: a sparser augmented matrix to factorise instead of K (semi-smooth
    Newton with ``schur`` or ``cg-factor``; see :func:`augmented_matrix`).
    """
    if name == "ssn":
        return SemismoothNewton(K, cdofs, lb, symmetric_positive, linear, options=options,
                                factor_matrix=factor_matrix)
    if name in ("vinewtonrsls", "vinewtonssls"):
        return SnesVI(K, cdofs, lb, symmetric_positive, snes_type=name, options=options)
    raise ValueError(f"unknown VI solver {name!r}; choose one of {', '.join(VI_SOLVERS)}")
