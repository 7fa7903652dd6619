"""What a run's linear strategy needs in memory, and what the machine has: ``auto``'s measure.

3-D (the ball, P2/P1, curved P2 tetrahedra): peak RSS of one rank, runs of 5-10 steps into
contact (``schur``: CHOLMOD of K below 20k rows, of the sparser augmented matrix above; few
cached columns), bench's run_case, dolfinx 0.5.2 / PETSc 3.18:

    level  dim W    schur      cg-gamg
    1        6594    472 MiB     315 MiB
    2       21750    980 MiB     752 MiB
    3       53976   2470 MiB    1739 MiB
    4      106842   5361 MiB    3392 MiB   (schur over 125 steps: 6.1 GB, the cached columns)

Nested dissection of a 3-D mesh leaves nnz(L) ~ n^(4/3) (2-D: n log n); a least-squares fit of
RSS - BYTES_PER_PROCESS = a n + c n^(4/3) over levels 2-4 gives a = 23 100 and c = 592 bytes
(levels 2-4 within 2 %, level 1 estimated at 0.76 of its RSS: the process's own libraries).
A factorised run also caches up to SCHUR_MAX_COLUMNS columns K^-1 e_i, 8 n bytes each, while they
take less than SCHUR_COLUMN_MEMORY (the 125-step level-4 run: +0.75 GB). The iterative fit (A and its
block copy, B, P, the multigrid, no factor, K never assembled: :mod:`sdm_dolfinx.method.matrix_free`) is
b n with b = 6 600 bytes (``cg-pmg``, levels 3-6: 6 635, 6 460, 6 408, 6 390; level 1: 213 MB measured
against 194 MB; before the step operator was matrix-free, 32 000). Level 5 (291 501 dofs) is estimated at 18.2 GB + 2 GB
of columns with ``schur``. In 2-D the factorisation always fitted at the sizes run (disc level 6,
512k dofs: 4.9 GB) and ``auto`` does not look at memory.
"""
from mpi4py import MPI

from sdm_dolfinx.solvers.factorisation import REDUNDANT_MAX_ROWS
from sdm_dolfinx.solvers.schur import SCHUR_COLUMN_MEMORY, SCHUR_MAX_COLUMNS

#: one process before any mesh (Python, dolfinx, PETSc, gmsh; measured 100-150 MB)
BYTES_PER_PROCESS = 150e6
#: factorised strategies in 3-D: bytes = FACTOR_3D[0] n + FACTOR_3D[1] n^(4/3), n = dim W^h
FACTOR_3D = (23100.0, 592.0)
#: ``cg-pmg`` and ``cg-gamg`` in 3-D (matrix-free): bytes = ITERATIVE_3D n
ITERATIVE_3D = 6600.0
#: ``auto`` factorises only when the estimate is below this fraction of the memory available per rank
MEMORY_MARGIN = 0.8
#: the share of a run's memory that does not divide among the ranks: on 2 ranks the largest held
#: 0.64-0.71 of the 1-rank peak (less BYTES_PER_PROCESS) with ``schur`` (levels 3-4) and 0.60-0.62
#: with ``cg-gamg`` (levels 3-5), i.e. a share s of 0.29-0.42 and 0.20-0.24 in s + (1 - s) / 2
#: (bench/results/ball*.json); the largest, rounded up. Measured at 1 and 2 ranks only.
SHARED = 0.45


def run_bytes(n, dim, factorised=True):
    """Estimated peak memory (bytes, one rank, BYTES_PER_PROCESS excluded) of a run with dim W^h
    = ``n`` in ``dim`` dimensions, factorising the step matrix or not; None for dim < 3 (the
    per-pair constants of :mod:`sdm_dolfinx.run.memory` apply)."""
    if dim < 3:
        return None
    if not factorised:
        return ITERATIVE_3D * n
    columns = min(8.0 * n * SCHUR_MAX_COLUMNS, SCHUR_COLUMN_MEMORY)
    return FACTOR_3D[0] * n + FACTOR_3D[1] * n ** (4.0 / 3.0) + columns


def factorisation_fits(n, dim, ranks, avail_per_rank):
    """(whether a factorised run of dim W^h = ``n`` in ``dim`` dimensions fits in MEMORY_MARGIN of
    ``avail_per_rank`` bytes (None: unknown, it fits), the bytes it needs per rank): above REDUNDANT_MAX_ROWS
    the factor is distributed (:func:`per_rank`), below each rank holds it all. ``auto``'s test
    (:func:`~sdm_dolfinx.solvers.active_set.choose_strategy`) and its memory estimate's."""
    need = run_bytes(n, dim)
    if n > REDUNDANT_MAX_ROWS:
        need = per_rank(need, ranks)
    return avail_per_rank is None or need <= MEMORY_MARGIN * avail_per_rank, need


def per_rank(total, ranks):
    """Bytes on each of ``ranks`` ranks of a distributed run that needs ``total`` on one:
    SHARED of it on every rank, the rest divided."""
    return total * (SHARED + (1.0 - SHARED) / ranks)


def mem_available():
    """MemAvailable of /proc/meminfo (bytes), or None where there is none (not collective)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        return None
    return None


def available_per_rank(comm=MPI.COMM_WORLD):
    """MemAvailable of /proc/meminfo divided by the ranks of ``comm`` on this node (bytes; the
    smallest over the nodes), or None where there is no /proc/meminfo."""
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    avail = None
    if node.rank == 0:
        total = mem_available()
        avail = None if total is None else total / node.size
    avail = node.bcast(avail, root=0)
    node.Free()
    vals = [a for a in comm.allgather(avail) if a is not None]
    return min(vals) if vals else None
