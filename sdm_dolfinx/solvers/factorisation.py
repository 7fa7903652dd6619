"""One sparse factorisation of the step matrix for the whole run (CHOLMOD or MUMPS, whichever
this PETSc has: :func:`factor_package`), with MUMPS's work-space retries.

:class:`Factorisation` solves x = K^-1 r for one right-hand side or many (the columns
K^-1 e_i of the Schur strategy), distributed with MUMPS or, for small matrices on several
ranks, redundantly (one copy per rank). It factorises K itself or a sparser augmented matrix
whose leading block's Schur complement is K (:mod:`sdm_dolfinx.solvers.augmented`).
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx.solvers.base import VIError
from sdm_dolfinx.solvers.options import scoped_options


class FactorPackageError(VIError):
    """This PETSc has no sparse direct solver for the factorisation asked for (one line)."""


def factor_package(serial, spd):
    """The sparse direct solver this PETSc has for one factorisation, on one process
    (``serial``: one rank, or one process's copy when the factorisation is redundant, see
    :class:`Factorisation`) or distributed.

    One process, SPD: CHOLMOD (supernodal Cholesky) where PETSc has SuiteSparse, measured 8x
    faster to factorise and 50-100x faster to solve with than MUMPS on the membrane's step
    matrix (MUMPS's solve phase costs ~1 us per node of its elimination tree, and PORD leaves
    ~one node per unknown; bench/factor_packages.py). Otherwise MUMPS (LDL^T for symmetric
    indefinite, distributed) where PETSc has it (Debian's PETSc has both; the PyPI wheel
    dolfinx-solver-real only MUMPS); on one process without either, PETSc's own factorisation.
    Which packages PETSc has is :func:`sdm_dolfinx.compat.petsc_has`'s answer.

    Raises:
        FactorPackageError: a distributed factorisation on a PETSc without MUMPS.
    """
    if serial and spd and compat.petsc_has("suitesparse"):
        return "cholmod"
    if compat.petsc_has("mumps"):
        return "mumps"
    if serial:
        return "petsc"
    raise FactorPackageError("this PETSc has no MUMPS, the only distributed sparse direct solver this package "
                             "uses: run on one rank, or with -sdm_factor_redundant 1, or choose --linear cg-gamg")


#: MUMPS's ICNTL(14): the percentage by which its work space exceeds the analysis's estimate.
#: MUMPS's default 20 % is not always enough on several ranks: on dolfinx 0.9 / PETSc 3.22
#: with 2 ranks the membrane P2/P1 factorisation failed in about 1 run in 3 with INFOG(1) = -9
#: (work array too small by a few dozen entries). :func:`factorise` starts from this value
#: and doubles it on -8/-9 failures.
MUMPS_ICNTL14 = 50


def mumps_margins(prefix, retries=4):
    """The successive attempts of a MUMPS factorisation: (attempt, ICNTL(14), options context).

    ICNTL(14) starts from ``-<prefix>mat_mumps_icntl_14`` or :data:`MUMPS_ICNTL14` and doubles
    at each retry; a retry overrides even a value given on the command line.
    """
    pct = PETSc.Options().getInt(prefix + "mat_mumps_icntl_14", MUMPS_ICNTL14)
    for attempt in range(retries + 1):
        yield attempt, pct, scoped_options(prefix, {"mat_mumps_icntl_14": str(pct)}, force=attempt > 0)
        pct *= 2


def factorise(M, comm, prefix, kind="cholesky", package="mumps", agree=None, retries=4):
    """A ``preonly`` KSP on ``comm`` holding a factorisation of M (set up: the factorisation
    is done).

    ``-<prefix>pc_factor_mat_solver_type`` and the other options under ``prefix`` override
    ``kind`` and ``package``. A MUMPS factorisation that runs out of work space (INFOG(1) =
    -8 or -9) is redone with twice the margin ICNTL(14) (:func:`mumps_margins`), up to
    ``retries`` times; any other failure raises :class:`VIError` naming MUMPS's error code.
    ``agree``: the mpi4py communicator whose ranks retry or fail together (default: comm's).
    """
    if agree is None:
        agree = comm.tompi4py() if hasattr(comm, "tompi4py") else comm
    for attempt, pct, margin in mumps_margins(prefix, retries):
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
        instead = "amg" if compat.petsc_has("hypre") else "cg-gamg"
        raise VIError(f"the factorisation of the {M.getSize()[0]}-row step matrix failed ({what}); "
                      f"see the MUMPS user guide, or choose --linear {instead}")
    raise AssertionError("unreachable")


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
            :func:`~sdm_dolfinx.solvers.augmented.augmented_matrix`); it is factorised instead of K.
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
        if aug is not None and spd:
            M.setOption(PETSc.Mat.Option.SYMMETRIC, True)
            # LDL^T of the symmetric (quasi-definite) indefinite matrix: not CHOLMOD's
            kind, package = "cholesky", factor_package(size1, False)
        elif aug is not None:           # a nonsymmetric K (a finite-strain tangent): LU of its augmented matrix
            kind, package = "lu", factor_package(size1, False)
        else:
            kind, package = ("cholesky" if spd else "lu"), factor_package(size1, spd)
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
        self.F.destroy()            # the handle's reference: else the factor outlives the KSP (240 MB a
        self.ksp.destroy()          # time for the ball's level-1 LU, a finite-strain run's every tangent)
        self.ra.destroy()
        self.xa.destroy()
        if self.redundant:
            self.M.destroy()
