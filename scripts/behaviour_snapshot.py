"""Record, or compare, the time series of a fixed set of runs (a refactoring's safety net).

    python scripts/behaviour_snapshot.py record FILE.npz      (1 rank, or under mpirun -n 2)
    python scripts/behaviour_snapshot.py compare OLD.npz NEW.npz [--rtol 1e-13]

The set: the membrane (N = 10, T = 0.8, dt = 1e-3) with every registered pair and both time
schemes (plus the consistent C of P2/P1 and P1+/P1), and the disc at level 1 (dt = 1e-4,
T = 0.02) with P2/P1 and P2/P2; then, declared problems run by name, friction (Coulomb, Tresca; 2-D and
3-D), the penalty and Nitsche treatments, every other scheme, PETSc's VI solver, the 1-D rod and
bar, and the constraint at every node (:data:`LAUNCHED`). 38 runs, about a minute. ``compare`` prints, per run and column, the largest difference
relative to the column's largest magnitude, and exits 1 when one exceeds ``--rtol``.
"""
import sys

import numpy as np


def _api():
    """(simulate, membrane.Problem, disc.Problem) of whichever package layout is installed."""
    try:
        from sdm_dolfinx.problems import disc, membrane
        from sdm_dolfinx.run import simulate
        return simulate, membrane.problem, disc.problem
    except ImportError:
        from sdm_dolfinx import disc, membrane, simulate
        return simulate, membrane.Problem, disc.Problem


RUNS = ([("membrane", pair, scheme, None) for pair in ("P1+/P0", "P1/P0", "P1/P1", "P1+/P1", "P2/P1", "P2/P2")
         for scheme in ("midpoint", "backward-euler")]
        + [("membrane", pair, "midpoint", "consistent") for pair in ("P2/P1", "P1+/P1")]
        + [("disc", pair, "midpoint", None) for pair in ("P2/P1", "P2/P2")])


#: (problem, its parameters, run options in run.json's flat spelling)
LAUNCHED = [
    ("block", {}, dict(friction="coulomb", mu=0.3, T=0.01)),
    ("block", {}, dict(friction="tresca", tresca_threshold=0.002, T=0.01)),
    ("block", {"start": "rest"}, dict(contact="penalty", T=0.005)),
    ("disc", {"level": 1}, dict(contact="nitsche", T=0.01)),
    ("disc", {"level": 1}, dict(contact="penalty", penalty=1e5, T=0.01)),
    ("disc", {"level": 1}, dict(constrain="nodes", T=0.01)),
    ("membrane", {"N": 8}, dict(scheme="newmark", T=0.4)),
    ("membrane", {"N": 8}, dict(scheme="hht", hht_alpha=-0.1, T=0.4)),
    ("membrane", {"N": 8}, dict(scheme="central-difference", pair="P1/P1", mass="row-sum", dt=5e-4, T=0.4)),
    ("membrane", {"N": 8}, dict(scheme="paoli-schatzman", pair="P1/P1", mass="row-sum", dt=5e-4, restitution=0.5,
                                T=0.4)),
    ("membrane", {"N": 8}, dict(scheme="taylor-flanagan", pair="P1/P1", mass="row-sum", dt=5e-4, T=0.4)),
    ("membrane", {"N": 8}, dict(vi_solver="vinewtonrsls", pair="P1+/P0", T=0.3)),
    ("membrane", {"N": 8}, dict(linear="cg-factor", pair="P2/P1", T=0.3)),
    ("rod1d", {}, dict(T=2.0)),
    ("bar", {}, dict(T=1.0)),
    ("ball", {"level": 1}, dict(friction="coulomb", mu=0.3, T=1.2e-3)),
]


def _launch(name, params, opts):
    """The declared problem ``name`` run with the flat options ``opts`` by whichever API is
    installed: ``simulate(name, params, **grouped(opts))``, or the older ``launch`` (flat)."""
    try:
        from sdm_dolfinx.run.options import grouped
    except ImportError:
        from sdm_dolfinx.run import launch
        return launch(name, params, **opts)
    from sdm_dolfinx.run import simulate
    return simulate(name, params, **grouped(opts))


def record(path):
    from mpi4py import MPI
    simulate, membrane, disc = _api()
    out = {}
    for kind, pair, scheme, mass in RUNS:
        if kind == "membrane":
            r = simulate(membrane(N=10), pair=pair, scheme=scheme, mass=mass, dt=1e-3, T=0.8)
        else:
            r = simulate(disc(level=1), pair=pair, scheme=scheme, mass=mass, dt=1e-4, T=0.02)
        key = f"{kind}|{pair}|{scheme}|{mass}"
        for col, values in r.timeseries.items():
            out[f"{key}|{col}"] = np.asarray(values)
        if MPI.COMM_WORLD.rank == 0:
            print(f"{key}: {len(r.timeseries['step']) - 1} steps", flush=True)
    for name, params, opts in LAUNCHED:
        key = f"{name}|{sorted(params.items())}|{sorted(opts.items())}"
        r = _launch(name, params, opts)
        for col, values in r.timeseries.items():
            out[f"{key}|{col}"] = np.asarray(values)
        if MPI.COMM_WORLD.rank == 0:
            print(f"{key}: {len(r.timeseries['step']) - 1} steps", flush=True)
    if MPI.COMM_WORLD.rank == 0:
        np.savez(path, **out)


def compare(old, new, rtol):
    a, b = np.load(old), np.load(new)
    worst, bad = 0.0, []
    missing = sorted(set(a.files) ^ set(b.files))
    for k in sorted(set(a.files) & set(b.files)):
        x, y = a[k], b[k]
        if x.shape != y.shape:
            bad.append(f"{k}: shape {x.shape} vs {y.shape}")
            continue
        scale = max(np.max(np.abs(x)), 1e-300)
        d = float(np.max(np.abs(x - y)) / scale) if x.size else 0.0
        worst = max(worst, d)
        if d > rtol:
            bad.append(f"{k}: {d:.3e}")
    print(f"{len(set(a.files) & set(b.files))} columns compared; largest relative difference {worst:.3e}")
    for m in missing:
        print(f"only in one file: {m}")
    for line in bad:
        print(f"over {rtol:g}: {line}")
    return 1 if bad else 0


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "record":
        record(sys.argv[2])
    elif len(sys.argv) >= 4 and sys.argv[1] == "compare":
        rtol = float(sys.argv[sys.argv.index("--rtol") + 1]) if "--rtol" in sys.argv else 1e-13
        sys.exit(compare(sys.argv[2], sys.argv[3], rtol))
    else:
        sys.exit(__doc__)
