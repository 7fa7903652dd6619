"""The one way to run: :func:`simulate` (and :func:`launch`, its deprecated former name for a
declared problem)."""
from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Optional, Union

from mpi4py import MPI

from sdm_dolfinx.method.pairs import Pair
from sdm_dolfinx.problems import Problem, ProblemSpec
from sdm_dolfinx.run import options as run_options
from sdm_dolfinx.run.loop import execute
from sdm_dolfinx.run.options import RunInputError
from sdm_dolfinx.io.folder import RunFolderError, read_info
from sdm_dolfinx.run.planning import Folder, check_folder, check_run, extension
from sdm_dolfinx.run.result import OnStep, Result
from sdm_dolfinx.solvers.options import unknown_option


def simulate(problem: Union[Problem, ProblemSpec, str, Path, None] = None, params: Optional[Mapping[str, Any]] = None,
             *, out: Optional[Folder] = None, overwrite: bool = False, restart: bool = False,
             allow_changed_source: bool = False, comm: Optional[MPI.Comm] = None, pair: Union[str, Pair, None] = None,
             scheme: Optional[str] = None, dt: Optional[float] = None, T: Optional[float] = None,
             mass: Optional[str] = None, vi_solver: Optional[str] = None, linear: Optional[str] = None,
             quadrature_degree: Union[int, str, None] = None, material: Optional[str] = None,
             newton: Optional[str] = None, friction: Optional[str] = None, constrain: Optional[str] = None,
             contact: Optional[str] = None, write_every: Optional[int] = None, checkpoint_every: Optional[int] = None,
             scheme_options: Optional[Mapping[str, Any]] = None, contact_options: Optional[Mapping[str, Any]] = None,
             friction_options: Optional[Mapping[str, Any]] = None,
             progress: bool = False, handle_signals: bool = False, on_step: Optional[OnStep] = None,
             observe: Optional[Callable[..., object]] = None, petsc_options: Optional[Mapping[str, Any]] = None,
             extra_info: Optional[Mapping[str, Any]] = None, constraint_tol: float = 1e-8,
             **deprecated: Any) -> Result:
    """Run a problem from t = 0 to T; every input is checked before anything is built or written.

    Args:
        problem: a :class:`~sdm_dolfinx.problems.Problem` (built: ``membrane.problem(N=10)``), or
            a declared problem: a registered name (``"membrane"``), a
            :class:`~sdm_dolfinx.problems.ProblemSpec` or the path of a problem file, built here
            from ``params`` and recorded in ``run.json`` so that a restart rebuilds it (not needed
            with ``restart``: the run in ``out`` says which).
        params: a declared problem's parameter values (its names; the others at their defaults).
        out: the output folder (``timeseries.csv``, ``run.json``, ``solution.xdmf``, ``state.h5``),
            or None: nothing written. A folder holding a run is refused unless ``overwrite``.
        overwrite: replace the run in ``out``.
        restart: continue the run in ``out`` from its checkpoint (same problem, parameters, options
            and ranks; only ``checkpoint_every`` may differ, and ``T`` to a later one: a finished run is
            extended so). ``allow_changed_source``: continue although the problem file or the package's
            version changed since the run started (refused otherwise); run.json records what changed.
        comm: the ranks of a declared problem (default ``MPI.COMM_WORLD``); a Problem's are its mesh's.
        pair, scheme, dt, T, mass, vi_solver, linear, quadrature_degree, material, newton, friction, constrain,
            contact, write_every, checkpoint_every: the run options (:data:`sdm_dolfinx.run.options.TABLE`:
            their values and defaults; None: the default, for ``pair``, ``scheme``, ``dt``, ``T`` and
            ``material`` a declared problem's own). ``pair`` may be a :class:`~sdm_dolfinx.method.pairs.Pair`.
        scheme_options, contact_options, friction_options: the options of the chosen scheme,
            contact treatment and friction law, as each declares them (docs/methods.md):
            ``{"hht_alpha": -0.1}``, ``{"penalty": 1e5}``, ``{"mu": 0.3}``; one given to a method
            not chosen is refused (it would be ignored).
        progress: print a progress line (rank 0) every few seconds.
        handle_signals: on SIGINT/SIGTERM stop after the current step, checkpoint, raise
            :class:`~sdm_dolfinx.run.Interrupted` (a signal during the set-up stops the run before
            anything is written).
        on_step: ``f(step, row)`` after every step with the time-series row (plus
            ``linear_its_total``); returning True requests a stop (as a signal would).
        observe: ``f(state)`` on every rank after row n (n = 0 too) of the time series, with a read-only
            :class:`~sdm_dolfinx.run.observe.State` (docs/api.md; ``f(n, t, U, V, integ)``: deprecated).
        petsc_options: PETSc options of this run's step solver (keys without prefix).
        extra_info: entries added to ``run.json``.
        constraint_tol: a constrained iterate below its bound by more than this (relative to the
            largest |bound|, or absolute when the bounds are 0) stops the run.
        deprecated: the flat spelling of a method's option (``mu=0.3``, ``penalty=1e5``,
            ``hht_alpha=-0.1``, ...): still accepted, with a FutureWarning naming the grouped one.

    Returns:
        :class:`~sdm_dolfinx.run.result.Result`.

    Raises:
        RunInputError: an input refused (every reason, one line; nothing written).
        StepError: a step failed (the outputs up to the last good step stay readable).
        Interrupted: a stop was requested; with ``out`` a checkpoint was written first.
        CheckpointError: ``restart`` without a matching checkpoint.
    """
    given = run_options.collect(
        {"pair": pair, "scheme": scheme, "dt": dt, "T": T, "mass": mass, "vi_solver": vi_solver, "linear": linear,
         "quadrature_degree": quadrature_degree, "material": material, "newton": newton, "friction": friction, "constrain": constrain, "contact": contact,
         "write_every": write_every, "checkpoint_every": checkpoint_every, "scheme_options": scheme_options,
         "contact_options": contact_options, "friction_options": friction_options, **deprecated})
    session: dict[str, Any] = dict(progress=progress, handle_signals=handle_signals, on_step=on_step,
                                   observe=observe, petsc_options=petsc_options, extra_info=extra_info,
                                   constraint_tol=constraint_tol)
    _refuse_early(petsc_options, allow_changed_source, restart)
    if isinstance(problem, Problem):
        if allow_changed_source:
            session["changed_source"] = ["allowed by the caller (allow_changed_source=True)"]
        return _run_built(problem, params, given, out, overwrite, restart, comm, session)
    comm = MPI.COMM_WORLD if comm is None else comm
    the_plan = check_run(problem, params, given, out=out, overwrite=overwrite, restart=restart, comm=comm,
                         allow_changed_source=allow_changed_source)
    return the_plan.run(comm, **session)


def _refuse_early(petsc_options: Optional[Mapping[str, Any]], allow_changed_source: bool, restart: bool) -> None:
    """RunInputError for a PETSc option no step solver reads, or allow_changed_source without a restart."""
    unknown = [m for m in map(unknown_option, petsc_options or {}) if m]
    if unknown:
        raise RunInputError("; ".join(unknown))
    if allow_changed_source and not restart:
        raise RunInputError("allow_changed_source is for a restart only (restart=True)")


def _run_built(problem: Problem, params: Optional[Mapping[str, Any]], given: dict[str, Any], out: Optional[Folder],
               overwrite: bool, restart: bool, comm: Optional[MPI.Comm], session: dict[str, Any]) -> Result:
    """:func:`simulate` of a built Problem: the same checks but of its parameters (built already)."""
    if params:
        raise RunInputError(f"params are the parameters of a declared problem; problem {problem.name!r} is built "
                            f"already (give its name, or build it with these values)")
    if comm is not None and MPI.Comm.Compare(comm, problem.mesh.comm) not in (MPI.IDENT, MPI.CONGRUENT):
        raise RunInputError(f"comm is not the ranks of problem {problem.name!r}'s mesh: leave it out")
    if restart and overwrite:
        raise RunInputError("a restart continues the run in out; remove overwrite")
    extended = _extension(out, given, problem.mesh.comm) if restart else None
    opts = run_options.complete(given)
    run_options.check(opts)
    seen = None if restart else check_folder(out, overwrite, problem.mesh.comm)
    return execute(problem, opts, out=out, restart=restart, folder_seen=seen, extended=extended, **session)


def _extension(out: Optional[Folder], given: dict[str, Any], comm: MPI.Comm) -> Optional[list[dict[str, Any]]]:
    """A built Problem's restart: the run's extensions to a later T (``given["T"]``; not given:
    the run's own T, set in ``given``); RunInputError for a T not later than the run's."""
    try:
        info = read_info(out, comm) if out is not None else None
    except RunFolderError:          # the checkpoint's check says what is missing
        return None
    if not info or "T" not in (info.get("run_options") or {}):
        return None
    given.setdefault("T", info["run_options"]["T"])
    try:
        return extension(info, given["T"], out)
    except RunFolderError as e:
        raise RunInputError(str(e)) from None


def launch(problem: Union[Problem, ProblemSpec, str, Path, None] = None,
           params: Optional[Mapping[str, Any]] = None, **kwargs: Any) -> Result:
    """Deprecated: :func:`simulate` runs a declared problem the same way (same arguments); a
    FutureWarning says so."""
    warnings.warn("sdm_dolfinx.run.launch() is deprecated: call sdm_dolfinx.simulate() with the same arguments",
                  FutureWarning, stacklevel=2)
    return simulate(problem, params, **kwargs)
