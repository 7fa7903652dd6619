"""Benchmark of the frictional step solver (:mod:`sdm_dolfinx.solvers.friction_newton`).

Two measurements on a plane-strain elastic block (P1, E = 1, nu = 0.3, [0, 2] x [0, 1], the
step matrix K = a2 M + A) pressed onto a shallow bowl and dragged sideways, its bottom
vertices the contact vertices:

* ``--study iterations``: Newton iterations per step of Tresca and of Coulomb solved by
  ``newton``, ``fixed-point`` and ``auto`` for mu = 0.05 ... 10, over 24 steps pressed,
  lifted and dragged back and forth (:func:`stress_loads`; xref = the previous step's x_t);
* ``--study cost``: the time per solve at ~50k dofs and ~200 contact vertices against the
  frictionless :class:`~sdm_dolfinx.solvers.SemismoothNewton` on the same K (``schur``; and
  ``schur*``, its dense Schur complement allowed beyond 100 active constraints), over the
  same sequence of loads, repeated: the median time per solve, the first solve's apart (it
  includes solving the cached columns), the set-up (factorisation) apart.

    .venv/bin/python bench/friction_solver.py --study iterations --nx 64 --ny 32
    .venv/bin/python bench/friction_solver.py --study cost --nx 200 --ny 125
"""
import argparse
import statistics
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.solvers import SemismoothNewton, VIError
from sdm_dolfinx.solvers import schur
from sdm_dolfinx.solvers.friction_newton import FrictionalNewton
from sdm_dolfinx.solvers.schur import SCHUR_MAX_ACTIVE

COMM = MPI.COMM_WORLD


def block(nx, ny, p=0.05, a2=0.01):
    """K, the pressing load, the unit drag, the contact dofs and bounds: the elastic block of the
    solver's unit tests (tests/unit/test_friction_solver.py, one definition for both)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "unit"))
    from test_friction_solver import elastic_block
    return elastic_block(nx, ny, p=p, a2=a2)[:6]


#: the drag of each step of the cost study, relative to q: dragged, more, held, back, back more
DRAGS = (1.0, 1.5, 1.5, 0.5, -0.5, -1.0)


def loads(b, drag, q):
    """The right-hand sides of the cost study's steps (new PETSc vectors)."""
    out = []
    for f in DRAGS:
        w = b.copy()
        w.axpy(q * f, drag)
        out.append(w)
    return out


def stress_loads(b, drag, nsteps=24):
    """The iterations study's steps: the press varies as 1.2 cos(2 pi k / 16) (so the block
    is also pulled off the bowl at times), and every 8th step from the 6th it is pulled by
    0.3 of the press; the drag is 0.02 sin(2 pi k / 7), back and forth."""
    out = []
    for k in range(nsteps):
        w = b.copy()
        w.scale(1.2 * np.cos(2 * np.pi * k / 16) if k % 8 != 5 else -0.3)
        w.axpy(0.02 * np.sin(2 * np.pi * k / 7), drag)
        out.append(w)
    return out


def run_steps(solver, rhs, tdofs, frictional=True):
    """Solve the sequence (xref: the previous step's x_t); per step (seconds, Newton its),
    None for a step that raised VIError (the next one starts again from no contact)."""
    x = rhs[0].duplicate()
    x.set(0.0)
    xref, out = np.zeros(len(tdofs)), []
    for w in rhs:
        t = time.perf_counter()
        try:
            info = solver.solve(w, x, xref) if frictional else solver.solve(w, x)
            out.append((time.perf_counter() - t, info["its"]))
        except VIError:
            out.append(None)
            solver._sets = None
        xref = x.array[tdofs].copy()
    x.destroy()
    return out


def iterations(nx, ny, a2):
    """Newton iterations per step of every law and method (the ``iterations`` study)."""
    K, b, drag, nd, td, lb = block(nx, ny, a2=a2)
    rhs = stress_loads(b, drag)
    if COMM.rank == 0:
        print(f"elastic block {nx} x {ny}, a2 = {a2:g}: {K.getSize()[0]} dofs, {COMM.allreduce(len(nd))} contact "
              f"vertices; {len(rhs)} steps: failed steps, Newton iterations per step (mean, max)")
    cases = [("tresca", c, None) for c in (1e-4, 1e-3, 5e-3)]
    cases += [("coulomb", mu, m) for mu in (0.05, 0.1, 0.2, 0.3, 0.5, 1.0, 2.0, 5.0, 10.0)
              for m in ("newton", "fixed-point", "auto")]
    for law, coef, method in cases:
        kw = dict(threshold=coef) if law == "tresca" else dict(mu=coef, coulomb=method)
        s = FrictionalNewton(K, nd, td, lb, law=law, **kw)
        its = [r[1] for r in run_steps(s, rhs, td) if r is not None]
        if COMM.rank == 0:
            print(f"  {law:8s}{coef:<7g}{method or '':12s} failed {len(rhs) - len(its):2d}   "
                  f"its mean {np.mean(its):5.2f} max {max(its, default=0):3d}")
        s.destroy()
    for w in rhs:
        w.destroy()


def cost(nx, ny, a2, repeat):
    """Time per solve against the frictionless solver (the ``cost`` study)."""
    K, b, drag, nd, td, lb = block(nx, ny, a2=a2)
    ncontact = COMM.allreduce(len(nd))
    rhs = loads(b, drag, 0.01)
    if COMM.rank == 0:
        print(f"elastic block {nx} x {ny}, a2 = {a2:g}: {K.getSize()[0]} dofs, {ncontact} contact vertices, "
              f"{COMM.size} rank(s); {len(DRAGS)} steps x {repeat}")
    cases = [("frictionless ssn schur", lambda: SemismoothNewton(K, nd, lb, linear="schur"), False),
             ("frictionless ssn schur*", lambda: SemismoothNewton(K, nd, lb, linear="schur"), False),
             ("coulomb mu=0 (frictionless)", lambda: FrictionalNewton(K, nd, td, lb, law="coulomb", mu=0.0), True),
             ("tresca s=2e-3", lambda: FrictionalNewton(K, nd, td, lb, law="tresca", threshold=2e-3), True)]
    cases += [(f"coulomb mu={mu:g} {m}", (lambda mu=mu, m=m: FrictionalNewton(K, nd, td, lb, law="coulomb",
                                                                             mu=mu, coulomb=m)), True)
              for mu in (0.3, 1.0) for m in ("newton", "fixed-point")]
    base = None
    for name, make, frictional in cases:
        # schur*: the dense Schur complement beyond its default SCHUR_MAX_ACTIVE = 100 (above
        # which schur solves by CG on the inactive set)
        schur.SCHUR_MAX_ACTIVE = 100_000 if name.endswith("*") else SCHUR_MAX_ACTIVE
        t = time.perf_counter()
        s = make()
        setup = time.perf_counter() - t
        times, its = [], []
        for _ in range(repeat):
            res = run_steps(s, rhs, td, frictional)
            times += [r[0] for r in res if r]
            its += [r[1] for r in res if r]
        med = statistics.median(times)
        base = med if base is None else base
        if COMM.rank == 0:
            print(f"  {name:28s} set-up {setup:6.2f} s   solve median {1e3 * med:8.1f} ms "
                  f"(first {1e3 * times[0]:7.1f} ms, x{med / base:5.2f})   Newton its {its[:len(DRAGS)]}  "
                  f"linear solves {s.total_linear_its}")
        s.destroy()
    schur.SCHUR_MAX_ACTIVE = SCHUR_MAX_ACTIVE


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", choices=("iterations", "cost"), default="iterations")
    parser.add_argument("--nx", type=int, default=None)
    parser.add_argument("--ny", type=int, default=None)
    parser.add_argument("--a2", type=float, default=0.01, help="the mass coefficient of K")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    if args.study == "iterations":
        iterations(args.nx or 32, args.ny or 16, args.a2)
    else:
        cost(args.nx or 200, args.ny or 125, args.a2, args.repeat)
