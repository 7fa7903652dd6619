"""The memory a run (or an inf-sup inspection) needs, estimated before it starts: a run that
would not fit in the machine's available memory is refused up front (:func:`check_memory`)."""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any, Optional, Union

from mpi4py import MPI

from sdm_dolfinx.method.pairs import Pair, get_pair
from sdm_dolfinx.run.options import RunInputError
from sdm_dolfinx.solvers.memory import factorisation_fits, mem_available, per_rank, run_bytes

if TYPE_CHECKING:
    from sdm_dolfinx.problems import ProblemSpec

# ---- memory estimates (measured with the run's maxrss on dolfinx 0.5.2 / PETSc 3.18, 1 rank,
# membrane N = 100 to 400 and disc levels 4-5, default solver; see estimate_memory)
#: bytes per dof of W^h and per component of u, by pair (the run's matrices, factorisation
#: or AMG hierarchy, vectors); the P?/P1 pairs pay for the denser M = B^T C^-1 B
BYTES_PER_DOF = {"P1+/P0": 1300, "P1/P0": 2200, "P1/P1": 1700, "P1+/P1": 3000, "P2/P1": 4000, "P2/P2": 1400}
#: for a pair not measured
DEFAULT_BYTES_PER_DOF = 4000
#: an inf-sup inspection (SuperLU of B B^T, ARPACK), any pair
INSPECT_BYTES_PER_DOF = 3000
#: solvers that factorise a matrix of K's size at every iteration need about twice as much
#: (measured: --linear lu, P2/P1, N = 100: 6.8 kB per dof)
REFACTORISING = 2.0
#: one process before any mesh: Python, dolfinx, PETSc, gmsh (measured 100-150 MB)
BYTES_PER_PROCESS = 150e6


def available_memory(comm=MPI.COMM_WORLD):
    """The machine's available memory in bytes (``MemAvailable`` of /proc/meminfo, read on
    rank 0), or None where there is no /proc/meminfo."""
    return comm.bcast(mem_available() if comm.rank == 0 else None, root=0)


def _lagrange_dofs(family, degree, counts):
    """Nodes of one component of a Lagrange (``P``), P1 + bubble (``P+``) or DG0 space on a
    triangle mesh with these entity counts."""
    v, e, c = counts["vertices"], counts["edges"], counts["cells"]
    if family == "P+":
        return v + c
    if degree == 0:
        return c
    return v + (degree - 1) * e + (degree - 1) * (degree - 2) // 2 * c


def estimate_memory(spec, values, pair, options=None, steps=0, ranks=1, inspect=False):
    """(bytes, dim W^h) that a run (or with ``inspect`` an inf-sup inspection) of ``spec``
    with parameter ``values`` and ``pair`` needs, or None when the problem declares no
    estimate (``spec.estimate(values)`` -> mesh entity counts, see the membrane).

    A model, not a measurement: bytes per dof of W^h (:data:`BYTES_PER_DOF`, per component
    of u: a vector problem's rows have twice the nonzeros), doubled for solvers that refactorise
    (:data:`REFACTORISING`), plus :data:`BYTES_PER_PROCESS` per rank and ~100 bytes per step of
    time series. Measured runs needed 0.75-0.9 times the estimate (membrane N = 100-400, every pair;
    disc levels 4-5; inspections 0.75). In 3-D (``counts["dim"]``, or a 3-component u) the
    factorisation's fill grows as n^(4/3): :func:`sdm_dolfinx.solvers.memory.run_bytes`, a fit of
    the ball's measured peak RSS (levels 1-4), of the factorised or the iterative strategy
    (``auto``: the factorised one where it fits, by ``auto``'s own test
    :func:`~sdm_dolfinx.solvers.memory.factorisation_fits`, else the iterative one); on
    several ranks each holds :func:`~sdm_dolfinx.solvers.memory.per_rank` of it (measured: not half
    on 2 ranks).
    """
    estimate = getattr(spec, "estimate", None)
    counts = estimate(values) if estimate is not None else None
    if counts is None:
        return None
    pair = get_pair(pair) if isinstance(pair, str) else pair
    vs = counts.get("value_size", 1)
    dim_w = vs * _lagrange_dofs(*pair.w, counts)
    dim = counts.get("dim", 3 if vs == 3 else 2)
    if not inspect and dim >= 3:     # 3-D: the factor's fill grows faster than n (solvers.memory)
        o = options or {}
        linear = o.get("linear", "auto")
        factorised = run_bytes(dim_w, dim, factorised=True)
        if o.get("vi_solver", "ssn") != "ssn" or linear == "lu":
            need = REFACTORISING * factorised
        elif linear in ("amg", "cg-amg", "cg-gamg", "cg-pmg"):
            need = run_bytes(dim_w, dim, factorised=False)
        elif linear == "auto":           # auto takes cg-pmg or cg-gamg when the factorisation does not fit
            avail = mem_available()
            fits, _ = factorisation_fits(dim_w, dim, ranks, None if avail is None else avail / ranks)
            need = factorised if fits else run_bytes(dim_w, dim, factorised=False)
        else:
            need = factorised
        return per_rank(need, ranks) * ranks + BYTES_PER_PROCESS * ranks + 100.0 * steps, dim_w
    if inspect:
        per_dof = INSPECT_BYTES_PER_DOF
    else:
        per_dof = BYTES_PER_DOF.get(pair.name, DEFAULT_BYTES_PER_DOF) * vs
        o = options or {}
        if o.get("linear") == "lu" or o.get("vi_solver", "ssn") != "ssn":
            per_dof *= REFACTORISING
    return float(per_dof) * dim_w + BYTES_PER_PROCESS * ranks + 100.0 * steps, dim_w


def check_memory(spec: ProblemSpec, values: Mapping[str, Any], pairs: Iterable[Union[str, Pair]],
                 comm: MPI.Comm = MPI.COMM_WORLD, cli: bool = False, options: Optional[Mapping[str, Any]] = None,
                 steps: int = 0, inspect: bool = False) -> None:
    """RunInputError when the estimated memory (:func:`estimate_memory`, the largest over
    ``pairs``) exceeds the machine's available memory: "--N 4500 needs about 79 GB (dim W^h =
    6.1e+07 with P1+/P0), this machine has 21 GB available"."""
    worst = None
    for pair in pairs:
        try:
            est = estimate_memory(spec, values, pair, options, steps, comm.size, inspect)
        except ValueError:          # an unknown pair: check_options says so
            continue
        if est is not None and (worst is None or est[0] > worst[0]):
            worst = (est[0], est[1], pair if isinstance(pair, str) else pair.name)
    if worst is None:
        return
    avail = available_memory(comm)
    if avail is None or worst[0] <= avail:
        return
    by = getattr(spec, "estimate")(values).get("by", ())
    what = " ".join(f"--{spec.param(k).option} {_value(values[k])}" if cli else f"{k} = {_value(values[k])}"
                    for k in by) or f"problem {spec.name}"
    raise RunInputError(f"{what} needs about {_gb(worst[0])} GB (dim W^h = {worst[1]:.2g} with {worst[2]}), this "
                        f"machine has {_gb(avail)} GB available")


def _value(v):
    return " ".join(map(str, v)) if isinstance(v, (tuple, list)) else str(v)


def _gb(b):
    """Bytes in GB for messages: 79, 2.4, or 1e+300."""
    g = b / 1e9
    if not math.isfinite(g) or g >= 1e6:
        return f"{g:.2g}"
    return f"{g:.0f}" if g >= 10 else f"{g:.2g}"
