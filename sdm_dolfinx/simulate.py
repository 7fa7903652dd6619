"""The time loop: Problem + Pair + scheme -> time series (and files, if asked)."""
import time
from dataclasses import dataclass, field
from pathlib import Path

from mpi4py import MPI

import numpy as np

from . import compat
from .discretisation import Discretisation
from .integrator import CONSTRAINED_ITERATE, Integrator, StepError
from .output import BASE_COLUMNS, ConstraintProbe, CSVWriter, PointProbe, XDMFWriter, write_json


@dataclass
class Result:
    """What a run produced.

    Attributes:
        timeseries: column name -> numpy array (one entry per step, entry 0 = initial state).
        info: what ``run.json`` holds (parameters, dofs, versions, wall time, ...).
        gap_imposed: per step, min over constraints of (constrained iterate - bound).
        gap_end: per step, min over constraints of (U^{n+1} - bound).
        U, V: final state vectors (PETSc, owned entries); V is Vbar in W, or V in H for the
            consistent block variant.
    """
    timeseries: dict
    info: dict
    gap_imposed: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gap_end: np.ndarray = field(default_factory=lambda: np.zeros(0))
    U: object = None
    V: object = None
    discretisation: object = None


def num_steps(T, dt):
    """Number of steps of length dt in [0, T] (T rounded to a multiple of dt)."""
    return int(np.floor(T / dt + 1e-9))


def simulate(problem, pair="P1+/P0", scheme="midpoint", dt=1e-3, T=0.8, mass=None, vi_solver="ssn",
             linear="cg-factor", out=None, write_every=None, progress=False, petsc_options=None,
             extra_info=None):
    """Run ``problem`` with ``pair`` and ``scheme`` from t = 0 to T.

    Args:
        problem: a :class:`sdm_dolfinx.problem.Problem`.
        pair: pair name (see :data:`sdm_dolfinx.pairs.PAIRS`).
        scheme: ``"midpoint"`` or ``"backward-euler"``.
        dt, T: time step and final time.
        mass: C treatment (``None``: the pair's default).
        vi_solver, linear, petsc_options: the step solver (see :mod:`sdm_dolfinx.vi`).
        out: output folder (``timeseries.csv``, ``run.json``, ``solution.xdmf``) or None.
        write_every: XDMF output every K steps (None: only with ``out``, every 10 steps).
        progress: print a progress line (rank 0) every few seconds.

    Returns:
        :class:`Result`.

    Raises:
        StepError: a step failed (the outputs up to the last good step stay readable).
    """
    wall0 = time.perf_counter()
    comm = problem.mesh.comm
    disc = Discretisation(problem, pair, mass)
    integ = Integrator(disc, scheme, dt, vi_solver, linear, petsc_options)
    nsteps = num_steps(T, dt)
    setup_time = time.perf_counter() - wall0
    columns = BASE_COLUMNS + tuple(problem.extra_columns)
    U, V = disc.initial_state()
    if integ.block:           # V in H^h with C V0 = B Vbar0 (condition (6) holds by construction)
        bv = disc.B.createVecLeft()
        disc.B.mult(V, bv)
        V = disc.solve_C(bv)
    probe = PointProbe(disc.W, problem.probe, problem.constraint_component)
    cprobe = ConstraintProbe(disc, problem.probe)
    info = {"problem": problem.describe(), "pair": disc.pair.name, "mass": disc.mass, "scheme": scheme,
            "dt": dt, "T": nsteps * dt, "steps": nsteps, "vi_solver": vi_solver, "linear": linear,
            **disc.dims(), "ranks": comm.size, "versions": compat.versions(),
            "displacement_reported": "U^{n+1} (end of step)",
            "constraint_imposed_on": CONSTRAINED_ITERATE[scheme],
            "lambda_probe": {"vertex": cprobe.vertex[:2].tolist(),
                             "definition": "nodal multiplier / lumped nodal measure (>= 0: obstacle pushes)"},
            "status": "running", **(extra_info or {})}
    writer = xdmf = None
    if out is not None:
        out = Path(out)
        if comm.rank == 0:
            out.mkdir(parents=True, exist_ok=True)
        comm.Barrier()
        write_json(out / "run.json", info, comm)
        writer = CSVWriter(out / "timeseries.csv", columns, comm)
        xdmf = XDMFWriter(out / "solution.xdmf", disc, integ)
        write_every = write_every or 10
    series = {c: np.zeros(nsteps + 1) for c in columns}
    gap_imposed, gap_end = np.zeros(nsteps), np.zeros(nsteps)
    lam = np.zeros(len(disc.cdofs))
    active = np.zeros(len(disc.cdofs), dtype=bool)

    def record(n, t, its, n_active):
        kin, pot = integ.energies(U, V)
        row = {"step": n, "t": t, "energy": kin + pot, "kinetic": kin, "potential": pot,
               "u_probe": probe(U), "lambda_probe": cprobe(lam), "n_active": n_active, "newton_its": its}
        if "contact_force" in columns:
            row["contact_force"] = comm.allreduce(float(np.sum(lam)), op=MPI.SUM)
        if "momentum_y" in columns:
            row["momentum_y"] = integ.momentum(V, problem.momentum_component)
        for c in columns:
            series[c][n] = row[c]
        if writer is not None:
            writer.write(row)
        if not np.isfinite(row["energy"]):
            raise StepError(f"step {n} (t = {t:.6g}): the energy is not finite ({row['energy']})")
        return row

    try:
        record(0, 0.0, 0, 0)
        if xdmf is not None:
            xdmf.write(U, V, lam, active, 0.0)
        last_print = time.perf_counter()
        for n in range(nsteps):
            t = n * dt
            info_step = integ.step(U, V, n, t)
            lam = integ.lam.copy()
            active = lam > 0
            gap_imposed[n], gap_end[n] = info_step["gap_imposed"], info_step["gap_end"]
            row = record(n + 1, (n + 1) * dt, info_step["its"], info_step["n_active"])
            if xdmf is not None and ((n + 1) % write_every == 0 or n + 1 == nsteps):
                xdmf.write(U, V, lam, active, (n + 1) * dt)
            if progress and comm.rank == 0 and (time.perf_counter() - last_print > 5 or n + 1 == nsteps):
                last_print = time.perf_counter()
                print(f"  step {n + 1}/{nsteps}  t = {(n + 1) * dt:.4g}  energy = {row['energy']:.6g}  "
                      f"active = {row['n_active']}  newton = {row['newton_its']}  "
                      f"[{last_print - wall0:.1f} s]", flush=True)
    except StepError as e:
        info.update(status="failed", error=str(e), wall_time=time.perf_counter() - wall0)
        if out is not None:
            write_json(out / "run.json", info, comm)
        raise
    finally:
        if writer is not None:
            writer.close()
        if xdmf is not None:
            xdmf.close()
    info.update(status="finished", wall_time=time.perf_counter() - wall0, setup_time=setup_time,
                newton_its_total=int(series["newton_its"].sum()),
                linear_its_total=int(integ.solver.total_linear_its),
                min_gap_imposed=float(gap_imposed.min(initial=np.inf)),
                min_gap_end=float(gap_end.min(initial=np.inf)))
    if out is not None:
        write_json(out / "run.json", info, comm)
    integ.destroy()
    return Result(series, info, gap_imposed, gap_end, U, V, disc)
