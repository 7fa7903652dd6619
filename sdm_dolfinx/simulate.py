"""The time loop: Problem + Pair + scheme -> time series (and files, if asked)."""
import signal
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from . import checkpoint, compat
from .discretisation import Discretisation
from .integrator import CONSTRAINED_ITERATE, Integrator, StepError
from .output import BASE_COLUMNS, ConstraintProbe, CSVWriter, PointProbe, StateWriter, XDMFWriter, write_json


class Interrupted(RuntimeError):
    """The run stopped at the end of a step on request (SIGINT/SIGTERM), after a checkpoint."""

    def __init__(self, message, signum):
        super().__init__(message)
        self.signum = signum


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
        discretisation: the :class:`Discretisation` (spaces, matrices).
    """
    timeseries: dict
    info: dict
    gap_imposed: np.ndarray = field(default_factory=lambda: np.zeros(0))
    gap_end: np.ndarray = field(default_factory=lambda: np.zeros(0))
    U: object = None
    V: object = None
    discretisation: object = None

    def displacement(self):
        """The final displacement U as a dolfinx Function of W^h (for plotting, probing, post-processing)."""
        return self._function(self.discretisation.W, self.U, "displacement")

    def velocity(self):
        """The final velocity as a dolfinx Function: Vbar in W^h, or V in H^h for the consistent block variant.

        Only M Vbar is determined by the scheme; with a singular M (dim H^h < dim W^h) Vbar also has
        a component in Ker(M) that carries no kinetic energy (see docs/outputs.md).
        """
        d = self.discretisation
        space = d.H if (d.mass == "consistent") else d.W
        return self._function(space, self.V, "velocity")

    def max_energy_deviation(self):
        """max_n |J^n - J^0| / |J^0| of the discrete energy (Theorem 2: 0 for the midpoint scheme without impact)."""
        E = np.asarray(self.timeseries["energy"])
        return float(np.max(np.abs(E - E[0])) / abs(E[0])) if E.size and E[0] != 0 else float("nan")

    @staticmethod
    def _function(space, vec, name):
        from dolfinx import fem
        f = fem.Function(space, name=name)
        f.x.array[:len(vec.array)] = vec.array
        f.x.scatter_forward()
        return f


def num_steps(T, dt):
    """Number of steps of length dt in [0, T] (T rounded to a multiple of dt)."""
    return int(np.floor(T / dt + 1e-9))


class _StopFlag:
    """SIGINT/SIGTERM set a flag; the loop stops at the end of the step (all ranks agree)."""

    def __init__(self, enabled):
        self.signum = 0
        self.old = {}
        if enabled:
            for s in (signal.SIGINT, signal.SIGTERM):
                self.old[s] = signal.signal(s, self._handler)

    def _handler(self, signum, frame):
        self.signum = signum

    def restore(self):
        for s, h in self.old.items():
            signal.signal(s, h)


def simulate(problem, pair="P1+/P0", scheme="midpoint", dt=1e-3, T=0.8, mass=None, vi_solver="ssn",
             linear="auto", out=None, write_every=None, progress=False, petsc_options=None,
             extra_info=None, checkpoint_every=None, restart=False, handle_signals=False, on_step=None,
             constraint_tol=1e-8):
    """Run ``problem`` with ``pair`` and ``scheme`` from t = 0 to T.

    Args:
        problem: a :class:`sdm_dolfinx.problem.Problem`.
        pair: pair name (see :data:`sdm_dolfinx.pairs.PAIRS`).
        scheme: ``"midpoint"`` or ``"backward-euler"``.
        dt, T: time step and final time.
        mass: C treatment (``None``: the pair's default).
        vi_solver, linear, petsc_options: the step solver (see :mod:`sdm_dolfinx.vi`).
        out: output folder (``timeseries.csv``, ``run.json``, ``solution.xdmf``) or None.
        write_every: XDMF output every K steps (default 10 when ``out`` is given).
        progress: print a progress line (rank 0) every few seconds.
        checkpoint_every: write ``out/checkpoint.npz`` every K steps (and at the end).
        restart: continue the run in ``out`` from its checkpoint (same parameters and ranks).
        handle_signals: on SIGINT/SIGTERM stop after the current step, checkpoint, raise
            :class:`Interrupted`.
        on_step: ``f(step, row)`` called after every step with the time-series row (plus
            ``linear_its_total``, the cumulative linear iterations); returning True requests
            a stop (as a signal would).
        constraint_tol: a constrained iterate below its bound by more than this (relative
            to the largest |bound|, or absolute when the bounds are 0) stops the run.

    Returns:
        :class:`Result`.

    Raises:
        StepError: a step failed (the outputs up to the last good step stay readable).
        Interrupted: a stop was requested; a checkpoint was written first.
        checkpoint.CheckpointError: ``restart`` without a matching checkpoint.
    """
    wall0 = time.perf_counter()
    comm = problem.mesh.comm
    disc = Discretisation(problem, pair, mass)
    try:
        integ = Integrator(disc, scheme, dt, vi_solver, linear, petsc_options)
    except PETSc.Error as e:            # e.g. a -sdm_ option PETSc does not accept
        raise SolverSetupError(f"PETSc could not set up the step solver: {_petsc_message(e)}") from None
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
    fingerprint = checkpoint.mesh_fingerprint(problem.mesh)
    identity = {"problem": problem.describe(), "pair": disc.pair.name, "mass": disc.mass, "scheme": scheme,
                "dt": dt, "vi_solver": vi_solver, "linear": linear, "ranks": comm.size, "mesh": fingerprint}
    info = {**identity, "T": nsteps * dt, "steps": nsteps, **disc.dims(), "versions": compat.versions(),
            "displacement_reported": "U^{n+1} (end of step)",
            "constraint_imposed_on": CONSTRAINED_ITERATE[scheme],
            "lambda_probe": {"vertex": cprobe.vertex[:2].tolist(),
                             "definition": "nodal multiplier / lumped nodal measure (>= 0: obstacle pushes)"},
            "status": "running", **(extra_info or {})}
    series = {c: np.zeros(nsteps + 1) for c in columns}
    gap_imposed, gap_end = np.zeros(nsteps), np.zeros(nsteps)
    lam = np.zeros(len(disc.cdofs))
    first = 0
    fields = {"U": (disc.W, U), "V": (disc.H if integ.block else disc.W, V)}
    if restart:
        if out is None:
            raise checkpoint.CheckpointError("restart needs the output folder of the run")
        data, meta = checkpoint.load(out, comm)
        _check_identity(meta["identity"], identity)
        if meta["step"] > nsteps:
            raise checkpoint.CheckpointError(f"the checkpoint is at step {meta['step']}, past T = {nsteps * dt}")
        previous = checkpoint.previous_run_id(out, comm)
        if meta.get("run_id") != previous:
            raise checkpoint.CheckpointError(
                f"{Path(out) / checkpoint.CHECKPOINT} was written by another run than the one in "
                f"{Path(out) / 'run.json'} (run_id {meta.get('run_id')} vs {previous})")
        outputs = checkpoint.check_outputs(out, meta["step"], comm)     # may move damaged files aside
        checkpoint.restore(data, fields, comm)
        integ.solver.active = checkpoint.active_mask(data, disc.cx)
        first = meta["step"]
        info["restarted_from_step"] = first
        run_id = previous
        if outputs["moved"] and comm.rank == 0:
            print(f"warning: {', '.join(n.replace('.damaged', '') for n in outputs['moved'] if n.endswith('.h5'))} "
                  f"could not be read (the run was killed while writing it): moved to "
                  f"{', '.join(outputs['moved'])}; the fields continue from step {first} in new files",
                  file=sys.stderr, flush=True)
    else:
        run_id = comm.bcast(uuid.uuid4().hex if comm.rank == 0 else None, root=0)
    info["run_id"] = run_id
    writer = xdmf = state = None
    if out is not None:
        out = Path(out)
        if comm.rank == 0:
            out.mkdir(parents=True, exist_ok=True)
            if not restart:         # a checkpoint of the run this one replaces must not be resumed
                (out / checkpoint.CHECKPOINT).unlink(missing_ok=True)
        comm.Barrier()
        write_json(out / "run.json", info, comm)
        if restart:
            rows = checkpoint.truncate_csv(out / "timeseries.csv", first, comm)
            for line in rows[1:]:
                vals = line.split(",")
                for c, v in zip(columns, vals):
                    series[c][int(vals[0])] = float(v)
            if outputs["solution"]:
                checkpoint.truncate_xdmf(out / "solution.xdmf", first * dt, comm)
        writer = CSVWriter(out / "timeseries.csv", columns, comm, append=restart)
        xdmf = XDMFWriter(out / "solution.xdmf", disc, integ, append=restart and outputs["solution"])
        state = StateWriter(out / "state.h5", disc, integ, fingerprint, append=restart and outputs["state"],
                            last_step=first)
        write_every = write_every or 10

    def write_fields(n):
        xdmf.write(U, V, lam, lam > 0, n * dt)
        state.write(U, V, n, n * dt)
    scale = max(comm.allreduce(float(np.max(np.abs(disc.lb), initial=0.0)), op=MPI.MAX), 1.0)
    stop = _StopFlag(handle_signals)

    def record(n, t, its, n_active):
        kin, pot = integ.energies(U, V)
        row = {"step": n, "t": t, "energy": kin + pot, "kinetic": kin, "potential": pot,
               "u_probe": probe(U), "lambda_probe": cprobe(lam), "n_active": n_active, "newton_its": its}
        if "contact_force" in columns:
            row["contact_force"] = comm.allreduce(float(np.sum(lam)), op=MPI.SUM)
        if "momentum_y" in columns:
            row["momentum_y"] = integ.momentum(V, problem.momentum_component)
        if "elastic" in columns:            # 1/2 U^T A U = potential + U^T L
            row["elastic"] = pot + U.dot(disc.L)
        row["linear_its_total"] = integ.solver.total_linear_its     # for on_step observers (not in the CSV)
        if not np.isfinite(row["energy"]):
            raise StepError(f"step {n} (t = {t:.6g}): the energy is not finite ({row['energy']})")
        for c in columns:
            series[c][n] = row[c]
        if writer is not None:
            writer.write(row)
        return row

    def save_checkpoint(n):
        meta = {"identity": identity, "step": n, "t": n * dt, "run_id": run_id}
        checkpoint.save(out, comm, fields, disc.cx[:, integ.solver.active].T, meta)

    saved, n = None, first
    try:
        if not restart:
            record(0, 0.0, 0, 0)
            if xdmf is not None:
                write_fields(0)
        elif state is not None and not outputs["state"]:
            state.write(U, V, first, first * dt)     # a new state.h5 starts at the checkpoint
        last_print = time.perf_counter()
        # the state before each step, so that a failed run's files end with its last good step
        saved = (U.array.copy(), V.array.copy()) if xdmf is not None else None
        for n in range(first, nsteps):
            t = n * dt
            if saved is not None:
                saved[0][:], saved[1][:] = U.array, V.array
                saved_lam = lam
            info_step = integ.step(U, V, n, t)
            lam = integ.lam.copy()
            gap_imposed[n], gap_end[n] = info_step["gap_imposed"], info_step["gap_end"]
            if gap_imposed[n] < -constraint_tol * scale:
                raise StepError(f"step {n + 1} (t = {(n + 1) * dt:.6g}): the constraint is violated by "
                                f"{-gap_imposed[n]:.3e} on the constrained iterate")
            row = record(n + 1, (n + 1) * dt, info_step["its"], info_step["n_active"])
            if xdmf is not None and ((n + 1) % write_every == 0 or n + 1 == nsteps):
                write_fields(n + 1)
            if progress and comm.rank == 0 and (time.perf_counter() - last_print > 5 or n + 1 == nsteps):
                last_print = time.perf_counter()
                print(f"  step {n + 1}/{nsteps}  t = {(n + 1) * dt:.4g}  energy = {row['energy']:.6g}  "
                      f"active = {row['n_active']}  newton = {row['newton_its']}  "
                      f"[{last_print - wall0:.1f} s]", flush=True)
            requested = bool(on_step(n + 1, row)) if on_step is not None else False
            signum = comm.allreduce(max(stop.signum, signal.SIGTERM if requested else 0), op=MPI.MAX)
            if out is not None and checkpoint_every and ((n + 1) % checkpoint_every == 0 or n + 1 == nsteps
                                                         or signum):
                save_checkpoint(n + 1)
            if signum and n + 1 < nsteps:
                msg = f"interrupted after step {n + 1} (t = {(n + 1) * dt:.6g})"
                if out is not None:
                    if not checkpoint_every:
                        save_checkpoint(n + 1)
                    msg += f"; checkpoint written, continue with --restart {out}"
                info.update(status="interrupted", interrupted_at_step=n + 1, wall_time=time.perf_counter() - wall0)
                if out is not None:
                    write_json(out / "run.json", info, comm)
                raise Interrupted(msg, signum)
    except StepError as e:
        info.update(status="failed", error=str(e), wall_time=time.perf_counter() - wall0)
        if out is not None:
            # step n was the last good one; its fields are written unless they already are
            if saved is not None and n > first and n % write_every:
                U.array[:], V.array[:] = saved
                lam = saved_lam
                write_fields(n)
            info["last_good_step"] = n
            write_json(out / "run.json", info, comm)
        raise
    finally:
        stop.restore()
        if writer is not None:
            writer.close()
    info.update(status="finished", wall_time=time.perf_counter() - wall0, setup_time=setup_time,
                newton_its_total=int(series["newton_its"].sum()),
                linear_its_total=int(integ.solver.total_linear_its),
                min_gap_imposed=float(gap_imposed[first:].min(initial=np.inf)),
                min_gap_end=float(gap_end[first:].min(initial=np.inf)))
    if out is not None:
        write_json(out / "run.json", info, comm)
    integ.destroy()
    return Result(series, info, gap_imposed, gap_end, U, V, disc)


class SolverSetupError(RuntimeError):
    """The step solver could not be set up (nothing was written)."""


def _petsc_message(e):
    """The informative line of a PETSc error (its last non-empty line) and its code."""
    lines = [ln.split("] ", 1)[-1].strip() for ln in str(e).splitlines() if ln.strip()]
    return f"{lines[-1] if lines else 'unknown error'} (PETSc error {getattr(e, 'ierr', '?')})"


def _check_identity(saved, now):
    """A checkpoint continues only the run that wrote it."""
    for key in ("problem", "pair", "mass", "scheme", "dt", "vi_solver", "linear", "ranks"):
        if saved.get(key) != now.get(key):
            raise checkpoint.CheckpointError(
                f"the checkpoint was written with {key} = {saved.get(key)!r}, this run has {now.get(key)!r}"
                + (" (restart on the same number of ranks)" if key == "ranks" else ""))
    if not checkpoint.same_fingerprint(saved["mesh"], now["mesh"]):
        raise checkpoint.CheckpointError("the checkpoint was written on a different mesh")
