"""Norms, errors and convergence rates (the disc's convergence study: paper Table 2, Fig. 16)."""
from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx import compat


def h1_norm(u, seminorm=False, l2_weight=1.0):
    """‖u‖_{H¹(Ω)} = (w ‖u‖²_{L²} + ‖∇u‖²_{L²})^½ (w = ``l2_weight``; 0 with ``seminorm``),
    reduced over ranks.

    The relative H¹ error depends on the length unit: lengths scaled by s (mm -> m:
    s = 1e-3) multiply the L² part by s² relative to the gradient part, so pass
    ``l2_weight = s**2`` for the norm in the other unit.
    """
    comm = u.function_space.mesh.comm
    expr = ufl.inner(ufl.grad(u), ufl.grad(u))
    if not seminorm:
        expr = expr + float(l2_weight) * ufl.inner(u, u)
    return float(np.sqrt(comm.allreduce(fem.assemble_scalar(compat.form(expr * ufl.dx)), op=MPI.SUM)))


def h1_error(u, u_ref, seminorm=False, l2_weight=1.0):
    """Relative H¹ error ‖u − u_ref‖ / ‖u_ref‖ (both in u_ref's space; see :func:`h1_norm`)."""
    e = fem.Function(u_ref.function_space)
    e.x.array[:] = u.x.array - u_ref.x.array
    return h1_norm(e, seminorm, l2_weight) / h1_norm(u_ref, seminorm, l2_weight)


def convergence_rate(h, err):
    """Least-squares slope of log(err) against log(h) (the convergence order)."""
    h, err = np.asarray(h, dtype=float), np.asarray(err, dtype=float)
    if len(h) < 2 or np.any(h <= 0) or np.any(err <= 0):
        raise ValueError("a rate needs at least two positive (h, error) pairs")
    return float(np.polyfit(np.log(h), np.log(err), 1)[0])
