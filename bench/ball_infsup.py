"""The inf-sup condition (7) of P1+ pairs on tetrahedra, measured on the ball.

A triangle's P1+ is P1 + the cubic bubble; basix refuses a cubic bubble on a tetrahedron
("Bubble element on a tetrahedron must have degree at least 4"): the tetrahedron's bubble is
the quartic lambda_0 lambda_1 lambda_2 lambda_3. P1+ on a tetrahedron is P1 + that bubble (vector,
3 components: the registered P1+ pairs on tetrahedra, ``compat.BUBBLE_DEGREE``), and measures condition (7)
with :func:`sdm_dolfinx.analysis.infsup.inspect` (the ``inspect`` command's numbers) for it with H^h =
P0 and P1, next to P2/P1, P1/P0 and P2/P2 on the same meshes: the ball at the given levels, and
(--cube N) the unit cube cut into N^3 x 6 tetrahedra with its bottom face constrained.

    .venv/bin/python bench/ball_infsup.py --levels 1 --cube 1 2 3 4
    .venv/bin/python bench/ball_infsup.py --levels 2 --cube --pairs P1+/P0 P1+/P1 P2/P1

Measured (1 rank; beta of condition (7), Euclidean norms; "ill" = ill-posed, beta = 0)::

    mesh          P1+4/P0           P1+4/P1           P2/P1    P1/P0   P2/P2
    cube n = 1    0.700  (42/18)    0.122  (42/24)    0.865    ill     ill
    cube n = 2    0.484  (225/144)  0.182  (225/81)   0.923    ill     ill
    cube n = 3    0.421  (678/486)  0.186  (678/192)  0.936    ill     ill
    cube n = 4    0.397  (1527/1152) 0.189 (1527/375) 0.939    ill     ill
    ball level 1  0.387  (4983/3978) 0.202 (4983/1005) 0.951   ill     ill     (N_g = 172)
    ball level 2  0.368  (17379/14331) 0.192 (17379/3048) 0.944  -     -      (N_g = 371)

(dim W / dim H in brackets.) Both P1+ pairs with the quartic bubble satisfy (7) with beta bounded
away from 0 under refinement; P1/P0 (dim Ker B = 9 on the cubes, 0 on the ball: the rigid motions
at most) and P2/P2 (Ker B = {0}) fail, as in 2-D. Energy through the impact (ball level 1,
midpoint, largest |E - E0|/E0): P1+4/P0 1.2 % at dt = 4e-5 s, 0.14 % at 1e-5 s; P1+4/P1 3.8 %,
0.24 % (P2/P1: 0.18 %, 0.21 %). The cube n = 6 is not measured: SciPy's ARPACK (``eigsh``, the
largest eigenvalue of B B^T in analysis/infsup.py's iterative path) did not converge for P1+4/P0
in 9 minutes (38881 iterations; the uniform mesh's clustered spectrum).
"""
import argparse
import json
import sys
import time

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx.method.pairs import get_pair
from sdm_dolfinx.analysis.infsup import inspect
from sdm_dolfinx.problems import Problem
from sdm_dolfinx.problems import ball


#: the pairs measured: the registered P1+ pairs (their bubble has degree 4 on a tetrahedron:
#: compat.BUBBLE_DEGREE) next to P2/P1 and the ill-posed P1/P0, P2/P2
PAIRS3D = [get_pair(n) for n in ("P1+/P0", "P1+/P1", "P2/P1", "P1/P0", "P2/P2")]


def cube_problem(n, comm=MPI.COMM_WORLD):
    """The unit cube (n^3 x 6 tetrahedra), elasticity, u_z >= 0 at the bottom face's vertices."""
    msh = dmesh.create_unit_cube(comm, n, n, n, dmesh.CellType.tetrahedron)
    bottom = lambda x: np.isclose(x[2], 0.0)
    fdim = 2
    msh.topology.create_connectivity(fdim, 3)
    facets = np.sort(dmesh.locate_entities_boundary(msh, fdim, bottom)).astype(np.int32)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=dmesh.meshtags(msh, fdim, facets, np.ones_like(facets)))(1)
    eps = lambda u: ufl.sym(ufl.grad(u))
    zero = fem.Constant(msh, np.zeros(3))       # a Constant: a literal zero would empty the form
    return Problem(name=f"cube{n}", mesh=msh, shape=(3,),
                   a=lambda u, w: ufl.inner(eps(u), eps(w)) * ufl.dx,
                   l=lambda w: ufl.inner(zero, w) * ufl.dx,
                   u0=lambda x: np.zeros((3, x.shape[1])), v0=lambda x: np.zeros((3, x.shape[1])),
                   constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom),
                   lower_bound=lambda x: np.zeros(x.shape[1]), constraint_component=2,
                   constraint_measure=lambda q: q * ds_c, probe=(0.5, 0.5, 0.0))


def measure_all(problems, dense_max, pairs):
    rows = []
    for label, make in problems:
        for pair in [p for p in PAIRS3D if p.name in pairs]:
            t0 = time.perf_counter()
            r = inspect(make(), pair, dense_max=dense_max)
            row = {k: r[k] for k in ("pair", "dim_W", "dim_H", "N_g", "rank_B", "dim_ker_B", "beta", "verdict",
                                     "reason", "method_short", "h")}
            row.update(mesh=label, seconds=time.perf_counter() - t0)
            rows.append(row)
            if MPI.COMM_WORLD.rank == 0:
                beta = "-" if row["beta"] is None else f"{row['beta']:.4e}"
                print(f"{label:10s} {row['pair']:8s} dim W {row['dim_W']:6d} dim H {row['dim_H']:6d} "
                      f"N_g {row['N_g']:4d} "
                      f"dim Ker B {row['dim_ker_B']:6d} beta {beta:>11s} {row['verdict']:11s} ({row['method_short']}, "
                      f"{row['seconds']:.1f} s)", flush=True)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="*", default=[1])
    ap.add_argument("--cube", type=int, nargs="*", default=[1, 2, 3, 4])
    ap.add_argument("--dense-max", type=int, default=3000)
    ap.add_argument("--pairs", nargs="*", default=[p.name for p in PAIRS3D])
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    problems = [(f"cube n={n}", lambda n=n: cube_problem(n)) for n in args.cube]
    problems += [(f"ball L{lev}", lambda lev=lev: ball.problem(level=lev)) for lev in args.levels]
    rows = measure_all(problems, args.dense_max, args.pairs)
    if args.json and MPI.COMM_WORLD.rank == 0:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
