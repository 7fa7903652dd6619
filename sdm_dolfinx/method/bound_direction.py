"""Does the bound name the component it bounds? A check of the constraint's direction.

A rigid floor or wall x_j + u_j >= p is declared as ``lower_bound(x) = p - x[j]`` on
``constraint_component = j``: the bound falls with slope -1 along the axis of the component it
bounds. A bound that falls with slope -1 along another axis j while not depending on the bounded
component's own coordinate describes the obstacle x_j + u_j >= p, yet holds u_c: the body passes
through that obstacle with no contact ever detected (a cube meant to rest on z = 0, constrained
in x, fell through it). :func:`misdirected_bound` finds that, by differences of ``lower_bound`` at
the constrained vertices, before anything runs.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.problems.base import bound_at

#: slopes within this of -1 (or of 0) count as -1 (or 0)
SLOPE_TOL = 1e-6


def misdirected_bound(problem, cx, comm):
    """A one-line message when ``problem``'s bound at the constrained vertices ``cx`` ((3, n), owned)
    is the obstacle of another component than ``constraint_component`` (see the module), else None
    (also for a scalar u). Collective."""
    shape = tuple(problem.shape)
    c = problem.constraint_component
    if not shape or c is None or problem.lower_bound is None:      # obstacles, contact pairs: no bound
        return None
    gdim = shape[0]
    x = problem.mesh.geometry.x
    extent = comm.allreduce(float(np.ptp(x, axis=0).max()) if len(x) else 0.0, op=MPI.MAX)
    h = 1e-3 * extent if extent > 0 else 1e-3
    g0 = np.asarray(bound_at(problem, cx), dtype=float).reshape(-1)
    slopes = []
    for j in range(gdim):
        x = np.array(cx, dtype=float, copy=True)
        x[j] += h
        d = (np.asarray(bound_at(problem, x), dtype=float).reshape(-1) - g0) / h
        # (max |slope + 1|, max |slope|) over the owned vertices, then over the ranks
        local = (float(np.max(np.abs(d + 1.0), initial=0.0)), float(np.max(np.abs(d), initial=0.0)))
        slopes.append(tuple(comm.allreduce(v, op=MPI.MAX) for v in local))
    n = comm.allreduce(len(g0), op=MPI.SUM)
    if n == 0 or slopes[c][1] > SLOPE_TOL:          # the bound depends on x_c: the usual x_c + u_c >= g form
        return None
    j = next((k for k in range(gdim) if k != c and slopes[k][0] <= SLOPE_TOL), None)
    if j is None:
        return None
    axis = "xyz"[j]
    return (f"problem {problem.name!r}: lower_bound(x) falls with slope -1 along {axis} (the obstacle {axis} + u_{axis} "
            f">= ...) but constraint_component = {c} bounds u_{'xyz'[c]}: the body would pass through that obstacle "
            f"unseen; set constraint_component = {j}")
