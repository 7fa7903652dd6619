"""A Problem's data where the discretisation reads it, refused in one line naming the problem's
file (or name) on every rank when it cannot make a run: constraint vertices that are not the
mesh's, a bound that is not one finite number per point, an initial state that is not finite.
(Without these checks they failed at step 0 with a NaN energy, or as an internal error.)"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.problems.base import bound_at, label, one_line
from sdm_dolfinx.problems.contact_pairs import constrained_vertices
from sdm_dolfinx.problems.errors import ProblemInputError


def refuse(problem, comm, wrong):
    """DiscretisationError on every rank when any rank found the problem's data ``wrong`` (a
    message; None: fine here)."""
    found = [m for m in comm.allgather(wrong) if m]
    if found:
        raise DiscretisationError(f"{label(problem)}: {found[0]}")


def vertices(problem, comm):
    """``problem.constraint_vertices(mesh)``: local vertex indices (0 .. owned + ghost vertices - 1)."""
    msh = problem.mesh
    nall = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    wrong = None
    try:
        verts = np.asarray(constrained_vertices(problem, msh))
    except ProblemInputError as e:          # on this rank: refused on every rank below
        verts, wrong = np.zeros(0, dtype=np.int32), str(e).removeprefix(f"problem {problem.name!r}: ")
    if wrong is None and verts.size and not np.issubdtype(verts.dtype, np.integer):
        wrong = f"constraint_vertices returned {verts.dtype} values, not vertex indices (integers)"
    elif wrong is None and verts.size and (verts.min() < 0 or verts.max() >= nall):
        wrong = (f"constraint_vertices returned vertex indices outside 0..{nall - 1}, the mesh's local vertices "
                 f"(got {int(verts.min())}..{int(verts.max())})")
    refuse(problem, comm, wrong)
    return verts.astype(np.int32).reshape(-1)


def bound(problem, x, comm, t=0.0):
    """``problem.lower_bound(x)`` (a moving bound: ``lower_bound(x, t)``) at the points ``x`` (3, n):
    n finite numbers. A Problem with ``obstacles`` has no such bound: NaN (every gap of it is
    :mod:`.obstacle_rows`'s, and a NaN can never pass for a gap)."""
    if getattr(problem, "obstacles", ()) or getattr(problem, "contact_pairs", ()):
        return np.full(x.shape[1], np.nan, dtype=PETSc.ScalarType)
    moving, wrong = getattr(problem, "moving_bound", False), None
    try:
        lb = np.asarray(bound_at(problem, x, t))
    except TypeError as e:          # a bound of x called with (x, t), or the other way round
        lb = np.zeros(x.shape[1])
        hint = ("moving_bound=True: lower_bound takes (x, t)" if moving else
                "a bound that takes (x, t) needs Problem(moving_bound=True)")
        wrong = (f"lower_bound({'x, t' if moving else 'x'}) failed ({one_line(e)})"
                 + (f": {hint}" if "positional argument" in str(e) else ""))
    if wrong is None and lb.shape != (x.shape[1],):
        wrong = (f"lower_bound returned an array of shape {lb.shape} for x of shape {x.shape}; it must return "
                 f"shape ({x.shape[1]},), the bound at each point")
    elif wrong is None and not np.all(np.isfinite(lb)):
        bad = ~np.isfinite(lb)
        wrong = f"lower_bound returned non-finite values ({lb[bad][0]}) at {int(np.sum(bad))} point(s)"
        if moving:
            wrong += f" at t = {t:.6g}"
    refuse(problem, comm, wrong)
    return lb.astype(PETSc.ScalarType)


def initial_finite(problem, U, V, comm):
    """The interpolants of ``u0`` and ``v0`` (PETSc vectors U, V) are finite."""
    for name, vec in (("u0", U), ("v0", V)):
        bad = comm.allreduce(int(np.sum(~np.isfinite(vec.array))), op=MPI.SUM)
        if bad:
            raise DiscretisationError(f"{label(problem)}: {name} gives non-finite values (nan or inf) at {bad} dof(s) "
                                      f"of W^h")
