"""The time loop: Problem + Pair + scheme -> time series (and files, if asked).

:func:`execute` is the loop behind :func:`sdm_dolfinx.run.simulate`; the pieces it drives live
beside it: the integrator (one step), :class:`~sdm_dolfinx.run.result.TimeSeries` (one row per step),
:class:`~sdm_dolfinx.io.run_files.RunFiles` (the folder), :mod:`.restart` (checkpoints) and
:mod:`.signals` (stopping cleanly).
"""
from __future__ import annotations

import time
import uuid
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional, Union

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx import compat
from sdm_dolfinx.contact import friction as _friction
from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.method.bound_direction import misdirected_bound
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.solvers import VIError
from sdm_dolfinx.errors import StepError
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.mpiutil import atomic_write_text, json_text
from sdm_dolfinx.run import options as run_options, restart as _restart
from sdm_dolfinx.io import checkpoint
from sdm_dolfinx.io.folder import FolderLock, RunFolderError, read_info, same_run_as_checked
from sdm_dolfinx.run.probes import ConstraintProbe, PointProbe
from sdm_dolfinx.io.run_files import RunFileError, RunFiles
from sdm_dolfinx.run.observe import Observer
from sdm_dolfinx.run.result import OnStep, Result, TimeSeries, num_steps
from sdm_dolfinx.run.signals import Interrupted, StopFlag
from sdm_dolfinx.run.solver_state import SolverHistory

if TYPE_CHECKING:
    from sdm_dolfinx.problems import Problem


class SolverSetupError(SdmError, RuntimeError):
    """The step solver could not be set up (nothing was written)."""


def execute(problem: Problem, options: Mapping[str, Any], *, out: Union[str, Path, None] = None,
            restart: bool = False, progress: bool = False, petsc_options: Optional[Mapping[str, Any]] = None,
            extra_info: Optional[Mapping[str, Any]] = None, handle_signals: bool = False,
            on_step: Optional[OnStep] = None, observe: Optional[Callable[..., object]] = None,
            constraint_tol: float = 1e-8, folder_seen: Optional[Mapping[str, Any]] = None,
            changed_source: Optional[list[str]] = None, extended: Optional[list[dict[str, Any]]] = None) -> Result:
    """Run ``problem`` with the checked, complete flat run ``options``
    (:func:`sdm_dolfinx.run.options.complete`) from t = 0 to T: the body of
    :func:`sdm_dolfinx.run.simulate`, whose documentation says what the keywords do;
    ``folder_seen`` is ``{"run_id": ...}`` that :func:`sdm_dolfinx.io.folder.check_out` saw in
    ``out`` (None: no check), checked again once the folder is locked; ``changed_source`` (a
    restart allowed to continue with a changed problem file or package: what changed, in words)
    relaxes the checkpoint's identity check for those and is recorded in run.json, as is
    ``extended`` (a restart: the run's extensions to a later T,
    :func:`sdm_dolfinx.run.planning.extension`).

    Returns:
        :class:`Result`.
    """
    wall0 = time.perf_counter()
    o = dict(options)
    run_options = {**o, "pair": o["pair"] if isinstance(o["pair"], str) else o["pair"].name}
    law = _friction.make(o["friction"], o.get("mu"), o.get("tresca_threshold"))   # checked: they agree
    stop = StopFlag(handle_signals)      # before anything is built or written
    loop = None
    kept = _kept_choice(out, o["linear"], problem.mesh.comm) if restart else None
    try:
        loop = _Loop(problem, o, petsc_options, wall0, law, kept)
        loop.observe = Observer(observe, loop.comm) if observe is not None else None     # or ObserveError
        if on_step is not None or (observe is not None and not getattr(observe, "read_only", False)):
            loop.discretisation.frozen.watch_forms()        # user code runs during the run: watch the forms too
        signum = stop.agreed(loop.comm)
        if signum:
            raise Interrupted("interrupted during the set-up, before anything was written", signum)
        extra = {"run_options": run_options, **(extra_info or {}),
                 **({"continued_with_changed_source": list(changed_source)} if changed_source else {}),
                 **({"extended": list(extended)} if extended else {})}
        loop.open(out, restart, o["write_every"], extra, folder_seen)
        loop.run(stop, progress, on_step, o["checkpoint_every"], constraint_tol)
        return loop.finish()
    finally:
        if loop is not None:
            loop.close()
        stop.restore()


def _kept_choice(out, linear, comm):
    """(strategy, reason) of the run in ``out`` when ``linear`` is ``auto``, else None: in 3-D
    ``auto`` decides by the memory free when the run starts, and a restart on a busier machine must
    continue on the same path (a different solver differs at round-off, or worse)."""
    if linear != "auto" or out is None:
        return None
    try:
        info = read_info(out, comm)
    except RunFolderError:          # the restart itself says what is missing
        return None
    chosen = info.get("linear_strategy")
    if chosen not in ("schur", "amg", "cg-gamg", "cg-pmg"):
        return None
    return chosen, f"auto, kept from the run's start ({info.get('linear_strategy_reason')})"


def _factor_package(integ):
    """The sparse direct solver of the step solver's one factorisation for the run ("cholmod",
    "mumps" or "petsc": :func:`~sdm_dolfinx.solvers.factorisation.factor_package`, what this PETSc
    has), or None when its strategy keeps none (``amg``, ``cg-gamg``, ``cg-pmg``, ``lu``, SNES VI)."""
    fac = getattr(getattr(integ, "solver", None), "fac", None)
    return getattr(fac, "package", None)


class _Loop:
    """The state of one run between :func:`simulate`'s phases (set-up, files, steps, end)."""

    def __init__(self, problem, o, petsc_options, wall0, friction=None, kept=None):
        dt, scheme, vi_solver, linear = o["dt"], o["scheme"], o["vi_solver"], o["linear"]
        self.wall0, self.dt, self.comm = wall0, dt, problem.mesh.comm
        self.discretisation = d = Discretisation(problem, o["pair"], o["mass"], o["quadrature_degree"],
                                                 constrain=o["constrain"] or "vertices")
        wrong = misdirected_bound(problem, d.cx, d.comm)        # the bound names another component
        if wrong:
            raise DiscretisationError(wrong)
        try:
            self.integ = Integrator(
                d, scheme, dt, vi_solver, kept[0] if kept else linear, petsc_options, friction,
                scheme_options={p.name: o.get(p.name) for p in run_options.options_of("scheme", scheme)},
                contact=o["contact"] or "exact",
                contact_options={p.name: o.get(p.name) for p in run_options.options_of("contact", o["contact"])},
                material=o["material"] or "linear", newton=o["newton"] or "full")
        except (PETSc.Error, VIError) as e:  # e.g. a -sdm_ option PETSc (or the step solver) does not accept
            raise SolverSetupError(f"PETSc could not set up the step solver: {_petsc_message(e)}") from None
        if kept:
            self.integ.linear_reason = kept[1]
        self.nsteps = num_steps(o["T"], dt)
        self.setup_time = time.perf_counter() - wall0
        U, V = d.initial_state(self.integ.friction, self.integ.contact)
        self.U, self.V = U, self.integ.initial_velocity(V)
        self.cprobe = ConstraintProbe(d, problem.probe)
        probe = PointProbe(d.W, problem.probe, problem.constraint_component)
        integ = self.integ
        self.series = TimeSeries(integ, d, problem, probe, self.cprobe, self.nsteps,
                                 friction=integ.friction is not None, contact_energy=integ.treatment is not None)
        self.gap_imposed, self.gap_end = np.zeros(self.nsteps), np.zeros(self.nsteps)
        self.lam = np.zeros(len(d.cdofs))
        self.fingerprint = checkpoint.mesh_fingerprint(problem.mesh)
        self.identity = {"problem": problem.describe(), "sdm_dolfinx": compat.package_version(),
                         "pair": d.pair.name, "mass": d.mass, "scheme": scheme,
                         "dt": dt, "vi_solver": vi_solver, "linear": linear, "ranks": self.comm.size,
                         "mesh": self.fingerprint,
                         **({"friction": friction.describe()} if friction is not None and friction.on else {}),
                         **({"material": o["material"], "newton": o["newton"] or "full"}
                            if self.integ.finite_strain else {}),
                         **_method_identity(o)}
        self.fields_of = {"U": (d.W, self.U), "V": (d.H if self.integ.block else d.W, self.V)}
        self.history = SolverHistory(self.integ)
        self.files = self.lock = None
        self.observe = None

    def open(self, out, restart, write_every, extra_info, folder_seen=None):
        """The folder's lock, run.json's first version, the restart (if any) and the files
        (if ``out``)."""
        d, integ = self.discretisation, self.integ
        self.info = {**self.identity, "T": self.nsteps * self.dt, "steps": self.nsteps, **d.dims(),
                     "quadrature_degree": d.quadrature_degree,
                     "versions": compat.versions(), "displacement_reported": "U^{n+1} (end of step)",
                     "constraint_imposed_on": integ.time_scheme.constrained,
                     "lambda_probe": {"vertex": self.cprobe.vertex[:2].tolist(),
                                      "definition": "nodal multiplier / lumped nodal measure (>= 0: obstacle pushes)"},
                     "solver_options_prefix": getattr(integ.solver, "prefix", None),
                     "linear_strategy": getattr(integ, "linear_strategy", None),
                     "linear_strategy_reason": getattr(integ, "linear_reason", None),
                     "step_matrix": "matrix-free" if getattr(integ, "matrix_free", False) else "assembled",
                     "factor_package": _factor_package(integ),
                     "status": "running", **extra_info}
        self.out, self.restarted, self.first = out, bool(restart), 0
        if out is not None:
            self.lock = FolderLock(out, self.comm)      # a second process in this folder stops here
            if folder_seen is not None and not restart:
                same_run_as_checked(out, folder_seen["run_id"], self.comm)
        if restart and getattr(integ, "stateful", False):
            raise checkpoint.CheckpointError(
                f"scheme {integ.scheme!r} keeps state between steps that a checkpoint does not hold (U and V "
                f"only): it cannot restart; rerun from t = 0")
        if restart:
            self.first, self.run_id, outputs = _restart.resume(
                out, self.identity, self.fields_of, integ, self.nsteps, self.comm, self.history,
                allow_changed_source=bool(extra_info.get("continued_with_changed_source")))
            self.info["restarted_from_step"] = self.first
        else:
            self.run_id = self.comm.bcast(uuid.uuid4().hex if self.comm.rank == 0 else None, root=0)
        self.info["run_id"] = self.run_id
        if out is not None:
            try:
                self.files = RunFiles(out, self.discretisation, self.series, self.info, self.fingerprint,
                                      (self.first, outputs) if restart else None, write_every, self.dt,
                                      block=integ.block, friction=integ.friction is not None)
            except RunFileError as e:
                self._say_failed(e)
                raise

    def record(self, n, its, n_active, step=None):
        integ = self.integ
        row = self.series.record(n, n * self.dt, self.U, self.V, self.lam, its, n_active, step,
                                 linear_its_total=integ.linear_its,
                                 slip=integ.slip_t if integ.friction is not None else None)
        if self.files is not None:
            self.files.row(row)
        if self.observe is not None:
            self.observe(n, n * self.dt, self.U, self.V, self.lam, integ)
        return row

    def fields(self, n, lam):
        """Write the fields of step ``n`` (the state's, with the contact forces ``lam``)."""
        integ = self.integ
        self.files.fields(n, self.U, self.V, lam, integ.lam_t_components if integ.friction is not None else None,
                          integ.slipping)

    def run(self, stop, progress, on_step, checkpoint_every, constraint_tol):
        """Steps first..nsteps; a failed step leaves the files at the last good step."""
        files, n = self.files, self.first
        d = self.discretisation
        rows = d.obstacle_rows if d.obstacle_rows is not None else d.body_rows
        bound = np.abs(d.lb[np.isfinite(d.lb)])       # NaN against obstacles and bodies: their gaps are distances
        scale = rows.size if rows is not None else max(self.comm.allreduce(float(np.max(bound, initial=0.0)),
                                                                            op=MPI.MAX), 1.0)
        saved = None
        try:
            if not self.restarted:
                self.record(0, 0, 0)
                if files is not None:
                    self.fields(0, self.lam)
            elif files is not None and files.state_missing:
                files.state_write(self.U, self.V, self.first)  # a new state.h5 starts here
            signum = stop.agreed(self.comm)
            if signum and self.first < self.nsteps:     # a signal during the set-up: the files exist now
                self.interrupted(self.first, signum, checkpointed=False)
            if progress and self.comm.rank == 0 and self.info["linear"] == "auto":
                info = self.info
                print(f"  linear strategy {info['linear_strategy']} ({info['linear_strategy_reason']})", flush=True)
            last_print = time.perf_counter()
            for n in range(self.first, self.nsteps):
                # the state before each step, so that a failed run's files end with its last good step
                saved = (self.U.array.copy(), self.V.array.copy(), self.lam) if files is not None else None
                row = self.step(n, scale * constraint_tol)
                if progress and self.comm.rank == 0 and (time.perf_counter() - last_print > 5 or n + 1 == self.nsteps):
                    last_print = time.perf_counter()
                    print(f"  step {n + 1}/{self.nsteps}  t = {(n + 1) * self.dt:.4g}  energy = {row['energy']:.6g}  "
                          f"active = {row['n_active']}  newton = {row['newton_its']}  "
                          f"[{last_print - self.wall0:.1f} s]", flush=True)
                requested = bool(on_step(n + 1, row)) if on_step is not None else False
                signum = stop.agreed(self.comm, requested)
                if files is not None and (checkpoint_every and ((n + 1) % checkpoint_every == 0 or signum)
                                          or n + 1 == self.nsteps and not self.integ.stateful):
                    self.checkpoint(n + 1)     # and at the end, whatever K: a finished run can be extended
                if signum and n + 1 < self.nsteps:
                    self.interrupted(n + 1, signum, checkpointed=bool(checkpoint_every))
        except StepError as e:
            self.failed(n, e, saved)
            raise

    def step(self, n, tol):
        """Step n -> n + 1: solve, check the constraint, record (and write the fields if due)."""
        info = self.integ.step(self.U, self.V, n, n * self.dt)
        self.lam = self.integ.lam.copy()
        self.gap_imposed[n], self.gap_end[n] = info["gap_imposed"], info["gap_end"]
        if self.gap_imposed[n] < -tol:
            raise StepError(f"step {n + 1} (t = {(n + 1) * self.dt:.6g}): the constraint is violated by "
                            f"{-self.gap_imposed[n]:.3e} on the constrained iterate")
        row = self.record(n + 1, info["its"], info["n_active"], info)
        if self.files is not None and self.files.due(n + 1, self.nsteps):
            self.fields(n + 1, self.lam)
        return row

    def checkpoint(self, n):
        _restart.save(self.out, self.identity, n, self.dt, self.run_id, self.fields_of, self.integ, self.comm,
                      self.files, self.history)

    def interrupted(self, n, signum, checkpointed):
        msg = f"interrupted after step {n} (t = {n * self.dt:.6g})"
        self.info.update(status="interrupted", interrupted_at_step=n, wall_time=time.perf_counter() - self.wall0)
        if self.files is not None and getattr(self.integ, "stateful", False):
            msg += f"; scheme {self.integ.scheme!r} cannot restart (state beyond U and V): rerun from t = 0"
            self.files.update()
        elif self.files is not None:
            if not checkpointed:
                self.checkpoint(n)
            msg += f"; checkpoint written, continue with: python -m sdm_dolfinx run --restart {self.out}"
            self.files.update()
        raise Interrupted(msg, signum)

    def failed(self, n, error, saved):
        """Step n was the last good one: run.json says so, and its fields are written unless they are.

        After a file error (:class:`RunFileError`) the last good step is the last row in the
        time series, and nothing more is written but run.json (for which a full disc gets
        the lock's reserve back)."""
        self.info.update(status="failed", error=str(error), wall_time=time.perf_counter() - self.wall0)
        if self.files is None:
            return
        if isinstance(error, RunFileError):
            self._say_failed(error, last_good_step=self.files.last_row)
            return
        try:
            if saved is not None and n > self.first and n % self.files.write_every:
                self.U.array[:], self.V.array[:] = saved[0], saved[1]
                self.fields(n, saved[2])
            self.files.update(last_good_step=n)
        except RunFileError as e:           # the step's error is the one to report
            self._say_failed(e, last_good_step=self.files.last_row, error=str(error))

    def _say_failed(self, error, **entries):
        """run.json says "failed" with ``error`` (best effort: the error is what matters)."""
        if getattr(error, "no_space", False) and self.lock is not None:
            self.lock.free_reserve()
        self.info.update(status="failed", error=str(error), wall_time=time.perf_counter() - self.wall0)
        self.info.update(entries)
        if self.comm.rank == 0:
            try:
                atomic_write_text(Path(self.out) / "run.json", json_text(self.info))
            except OSError:
                pass
        self.comm.Barrier()

    def close(self):
        """Close the files and unlock the folder (also after an error)."""
        if self.files is not None:
            self.files.close()
        if self.lock is not None:
            self.lock.release()
            self.lock = None

    def finish(self):
        self.series.warn_end()
        gi, ge = self.gap_imposed[self.first:], self.gap_end[self.first:]
        self.info.update(status="finished", wall_time=time.perf_counter() - self.wall0, setup_time=self.setup_time,
                         newton_its_total=int(self.series.data["newton_its"].sum()),
                         linear_its_total=int(self.integ.linear_its),
                         min_gap_imposed=float(gi.min(initial=np.inf)), min_gap_end=float(ge.min(initial=np.inf)),
                         **self.series.summary(self.first))
        if self.files is not None:
            try:
                self.files.update()
            except RunFileError as e:
                self._say_failed(e)
                raise
            self.files.tidy()
        self.integ.destroy()
        return Result(self.series.data, self.info, self.gap_imposed, self.gap_end, self.U, self.V, self.discretisation)


def _method_identity(o):
    """The method options that differ from their defaults (constraint at the vertices, exact
    contact, no scheme or treatment option given): they join the run's identity (run.json,
    checkpoints)."""
    defaults = run_options.complete({})
    return {k: o[k] for k in run_options.method_names() if o.get(k) is not None and o[k] != defaults[k]}


def _petsc_message(e):
    """The informative line of a PETSc error (its last non-empty line) and its code."""
    lines = [ln.split("] ", 1)[-1].strip() for ln in str(e).splitlines() if ln.strip()]
    return f"{lines[-1] if lines else 'unknown error'} (PETSc error {getattr(e, 'ierr', '?')})"

