"""The membrane over an obstacle (paper sections 3–4).

Omega = (0, 1)^2, u'' - Laplace(u) = f in Omega, u >= 0 (the obstacle), u = 0.02 on the
boundary, u(0) = 0.02, u'(0) = 0, f = -0.6; structured N x N mesh (h = 1/N).
"""
from mpi4py import MPI

import math

import numpy as np
import ufl
from dolfinx import mesh as dmesh

from . import problem as _problem

DIAGONALS = {"right": dmesh.DiagonalType.right, "left": dmesh.DiagonalType.left,
             "left_right": dmesh.DiagonalType.left_right, "right_left": dmesh.DiagonalType.right_left,
             "crossed": dmesh.DiagonalType.crossed}


def make_mesh(N, diagonal="right", comm=MPI.COMM_WORLD):
    """The unit square cut into N x N squares, each split into triangles (``diagonal``).

    ``left_right`` is GetFEM's ``regular simplices`` pattern used by the paper's program.
    """
    return dmesh.create_unit_square(comm, N, N, dmesh.CellType.triangle, diagonal=DIAGONALS[diagonal])


def Problem(N=10, f=-0.6, u0=0.02, g=0.02, obstacle=0.0, diagonal="right", probe=(0.5, 0.5),
             comm=MPI.COMM_WORLD, with_obstacle=True):
    """The paper's membrane problem.

    Args:
        N: squares per side (h = 1/N).
        f: the load.
        u0: initial displacement (constant).
        g: Dirichlet value on the whole boundary.
        obstacle: the obstacle height (u >= obstacle at every interior vertex).
        diagonal: mesh diagonal pattern (see :func:`make_mesh`).
        probe: point where the displacement and contact stress are recorded.
        with_obstacle: False removes the constraint (for energy-conservation checks).
    """
    msh = make_mesh(N, diagonal, comm)
    tdim = msh.topology.dim

    def boundary_facets(m):
        m.topology.create_connectivity(tdim - 1, tdim)
        return dmesh.exterior_facet_indices(m.topology)

    def interior_vertices(m):
        if not with_obstacle:
            return np.zeros(0, dtype=np.int32)
        nv = m.topology.index_map(0).size_local + m.topology.index_map(0).num_ghosts
        on_boundary = dmesh.locate_entities_boundary(m, 0, lambda x: np.isclose(x[0], 0) | np.isclose(x[0], 1)
                                                     | np.isclose(x[1], 0) | np.isclose(x[1], 1))
        mask = np.ones(nv, dtype=bool)
        mask[on_boundary] = False
        return np.flatnonzero(mask).astype(np.int32)

    return _problem.Problem(
        name="membrane", mesh=msh, shape=(),
        a=lambda u, w: ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx,
        l=lambda w: f * w * ufl.dx,
        u0=lambda x: np.full(x.shape[1], u0),
        v0=lambda x: np.zeros(x.shape[1]),
        constraint_vertices=interior_vertices,
        lower_bound=lambda x: np.full(x.shape[1], obstacle),
        constraint_measure=lambda q: q * ufl.dx,
        dirichlet_facets=boundary_facets,
        dirichlet_value=lambda x: np.full(x.shape[1], g),
        probe=probe,
        parameters={"N": N, "h": 1.0 / N, "f": f, "u0": u0, "g": g, "obstacle": obstacle, "diagonal": diagonal,
                    "with_obstacle": with_obstacle},
        units={"all": "dimensionless (paper section 4)"},
    )



#: defaults of the command line (paper section 4)
DEFAULTS = {"pair": "P1+/P0", "scheme": "midpoint", "dt": 1e-3, "T": 0.8, "time_unit": "dimensionless"}


def add_arguments(parser):
    """The membrane's own command-line options."""
    g = parser.add_argument_group("membrane (paper section 4; dimensionless)")
    g.add_argument("--N", type=int, default=10, help="squares per side of the unit square, h = 1/N (default 10)")
    g.add_argument("--diagonal", choices=sorted(DIAGONALS), default="right",
                   help="triangle pattern; left_right is GetFEM's 'regular simplices' of the paper (default right)")
    g.add_argument("--f", type=float, default=-0.6, help="load f (default -0.6)")
    g.add_argument("--u0", type=float, default=0.02, help="initial displacement (default 0.02)")
    g.add_argument("--g", type=float, default=0.02, help="Dirichlet value on the boundary (default 0.02)")
    g.add_argument("--obstacle", type=float, default=0.0, help="obstacle height (default 0)")
    g.add_argument("--no-obstacle", action="store_true", help="remove the constraint")
    g.add_argument("--probe", type=float, nargs=2, default=(0.5, 0.5), metavar=("X", "Y"),
                   help="probe point (default 0.5 0.5)")


def check_arguments(args):
    """Messages for out-of-range membrane options (empty list when all is well)."""
    errors = []
    if args.N < 1:
        errors.append(f"--N must be >= 1 (got {args.N})")
    if not all(0.0 <= c <= 1.0 for c in args.probe):
        errors.append(f"--probe must lie in the unit square (got {tuple(args.probe)})")
    for name in ("f", "u0", "g", "obstacle"):
        v = getattr(args, name)
        if not math.isfinite(v) or abs(v) > 1e150:    # squared in the energy: keep it finite
            errors.append(f"--{name} must be a finite number of magnitude <= 1e150 (got {v})")
    return errors


def problem_from_args(args, comm):
    """The membrane :func:`Problem` from the command line's parsed options."""
    return Problem(N=args.N, f=args.f, u0=args.u0, g=args.g, obstacle=args.obstacle, diagonal=args.diagonal,
                   probe=tuple(args.probe), comm=comm, with_obstacle=not args.no_obstacle)
