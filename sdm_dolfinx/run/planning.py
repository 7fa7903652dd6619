"""Checking a run before it starts: every input of a declared problem, the run options and the
output folder, in one :class:`RunInputError` giving every reason, before anything is written.

:func:`plan` checks and returns the :class:`RunPlan` without running it;
:func:`sdm_dolfinx.run.simulate` checks the same way, then runs. The run's problem, parameters
and options are recorded in ``run.json``, so a restart, the ``energy`` command and the pictures
rebuild the same run from the folder alone (:func:`_restart_plan`).
"""
from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional, Union

from mpi4py import MPI

from sdm_dolfinx import compat
from sdm_dolfinx.io.folder import RunFolderError, check_out, read_info
from sdm_dolfinx.method import quadrature
from sdm_dolfinx.problems import ProblemInputError, ProblemSpec, resolve, spec_of_run
from sdm_dolfinx.run import options as run_options
from sdm_dolfinx.run.loop import execute
from sdm_dolfinx.run.memory import check_memory
from sdm_dolfinx.run.options import RESTART_MAY_CHANGE, RunInputError
from sdm_dolfinx.run.result import OnStep, Result, num_steps

#: an output folder: a name or a path
Folder = Union[str, Path]


@dataclass
class RunPlan:
    """A checked run: the problem's declaration, its parameter values and the run options (flat,
    every one: :func:`sdm_dolfinx.run.options.complete`)."""
    spec: ProblemSpec
    params: dict[str, Any]
    options: dict[str, Any]
    out: Optional[Folder] = None
    restart: bool = False
    #: what the folder held when checked ({"run_id": ...}), checked again under the run's lock
    folder_seen: Optional[dict[str, Any]] = None
    #: a restart allowed to continue with a changed problem file or package: what changed
    changed_source: Optional[list[str]] = None
    #: the run's extensions to a later T (run.json's ``extended``), this restart's last
    extended: Optional[list[dict[str, Any]]] = None

    @property
    def steps(self) -> int:
        return num_steps(self.options["T"], self.options["dt"])

    def run(self, comm: MPI.Comm = MPI.COMM_WORLD, progress: bool = False, handle_signals: bool = False,
            on_step: Optional[OnStep] = None, petsc_options: Optional[Mapping[str, Any]] = None,
            extra_info: Optional[Mapping[str, Any]] = None, observe: Optional[Callable[..., object]] = None,
            constraint_tol: float = 1e-8) -> Result:
        """Build the problem and run it (the keywords are :func:`sdm_dolfinx.run.simulate`'s)."""
        problem = self.spec.problem(comm, **self.params)
        return execute(problem, self.options, out=self.out, restart=self.restart, progress=progress,
                       handle_signals=handle_signals, on_step=on_step, petsc_options=petsc_options,
                       extra_info=extra_info, observe=observe, constraint_tol=constraint_tol,
                       folder_seen=self.folder_seen, changed_source=self.changed_source, extended=self.extended)


def plan(problem: Union[ProblemSpec, str, Path, None] = None, params: Optional[Mapping[str, Any]] = None,
         *, out: Optional[Folder] = None, overwrite: bool = False, restart: bool = False,
         allow_changed_source: bool = False, comm: MPI.Comm = MPI.COMM_WORLD, cli: bool = False,
         **options: Any) -> RunPlan:
    """Check a run's inputs and the output folder; returns a :class:`RunPlan` (nothing written).

    Args:
        problem: a registered name, a :class:`~sdm_dolfinx.problems.ProblemSpec` or the path
            of a problem file (not needed with ``restart``).
        params: the problem's parameter values (its declared names; the rest at defaults).
        out, overwrite, restart, allow_changed_source: as :func:`sdm_dolfinx.run.simulate`'s.
        cli: name options and parameters ``--option`` in messages (the command line's spelling).
        options: the run options, as :func:`sdm_dolfinx.run.simulate` takes them.

    Raises:
        RunInputError: any refused input, with every reason.
    """
    given = run_options.collect(options, where="plan")
    return check_run(problem, params, given, out=out, overwrite=overwrite, restart=restart, comm=comm, cli=cli,
                     allow_changed_source=allow_changed_source)


def check_run(problem: Union[ProblemSpec, str, Path, None], params: Optional[Mapping[str, Any]],
              given: Mapping[str, Any], *, out: Optional[Folder] = None, overwrite: bool = False, restart: bool = False,
              comm: MPI.Comm = MPI.COMM_WORLD, cli: bool = False, allow_changed_source: bool = False) -> RunPlan:
    """The :class:`RunPlan` of a declared ``problem`` with the flat run options ``given``
    (:func:`sdm_dolfinx.run.options.collect`); RunInputError with every reason otherwise."""
    if restart and overwrite:
        raise RunInputError(f"a restart continues the run in {'--restart' if cli else 'out'}; remove "
                            f"{'--overwrite' if cli else 'overwrite'}")
    if problem is None and not restart:
        raise RunInputError("no problem: give a registered name, a problem file, a ProblemSpec or a Problem (or "
                            "restart=True with the run's out)")
    try:
        if restart:
            return _restart_plan(out, given, comm, problem, params, allow_changed_source, cli)
        assert problem is not None          # refused above
        spec = resolve(problem)
        run_options.check_problem_names(spec)
        values = spec.values(params, cli=cli)
    except (ProblemInputError, RunFolderError) as e:
        raise RunInputError(str(e)) from None
    opts = run_options.complete(given, spec.defaults)
    run_options.check(opts, cli)
    check_memory(spec, values, [opts["pair"]], comm, cli, options=opts, steps=num_steps(opts["T"], opts["dt"]))
    return RunPlan(spec, values, opts, out, folder_seen=check_folder(out, overwrite, comm, cli))


def check_folder(out: Optional[Folder], overwrite: bool, comm: MPI.Comm, cli: bool = False) -> Optional[dict[str, Any]]:
    """``{"run_id": ...}`` of the run ``out`` holds (None: none), to be checked again under the
    run's lock; None without ``out``. RunInputError for a folder name the file system cannot take,
    or a folder holding a run (or a damaged or foreign ``run.json``) without ``overwrite``."""
    if out is None:
        return None
    check_out_name(out, cli)
    try:
        return {"run_id": check_out(Path(out), overwrite, comm)}
    except RunFolderError as e:
        raise RunInputError(str(e)) from None


def check_out_name(out: Folder, cli: bool = False) -> None:
    """RunInputError for an output folder the file system cannot take: an empty name (which
    would be the current folder) or a name component longer than the file system allows
    (checked before any folder is created, so nothing is left behind)."""
    label = "--out" if cli else "out"
    if str(out).strip() == "":
        raise RunInputError(f"{label} is empty: name a folder (. for the current one)")
    path = Path(out)
    d = path if path.is_absolute() else Path.cwd()
    try:
        name_max = os.pathconf(_existing_parent(d), "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    for part in path.parts:
        if len(os.fsencode(part)) > name_max:
            short = part if len(part) <= 40 else part[:20] + "..." + part[-10:]
            raise RunInputError(f"{label} {short}: a folder name of {len(os.fsencode(part))} characters; the file "
                                f"system allows {name_max}")
    if len(os.fsencode(str(path.absolute()))) > 4000:
        raise RunInputError(f"{label}: the path is {len(os.fsencode(str(path.absolute())))} characters long; "
                            f"at most 4000")


def _existing_parent(path: Path) -> Path:
    while not path.exists():
        path = path.parent
    return path


def _restart_plan(out: Optional[Folder], given: Mapping[str, Any], comm: MPI.Comm,
                  problem: Union[ProblemSpec, str, Path, None] = None,
                  params: Optional[Mapping[str, Any]] = None, allow_changed_source: bool = False,
                  cli: bool = False) -> RunPlan:
    """The plan of the run in ``out`` to be continued (the options ``given`` must be the run's,
    but those of :data:`~sdm_dolfinx.run.options.RESTART_MAY_CHANGE`; ``problem``, if given, the
    run's problem; no ``params``: the run's own)."""
    if out is None:
        raise RunFolderError("a restart needs the run's folder (out)")
    if params:
        raise RunFolderError(f"a restart continues the run with its own parameters; remove params "
                             f"({', '.join(params)})")
    info = read_info(out, comm)
    if "run_options" not in info or "args" not in info.get("problem", {}):
        raise RunFolderError(f"{out}/run.json does not say how the run was started (written by an older version "
                             f"or by a problem built by hand): it cannot be continued")
    sources = source_changes(info)
    if sources and not allow_changed_source:
        how = (f"--restart {out} --allow-changed-source" if cli else "allow_changed_source=True")
        raise RunFolderError(f"{out}: {'; '.join(sources)} since the run started, so its physics may differ: "
                             f"rerun from t = 0, or restore the file; to continue with the change deliberately "
                             f"(run.json records it): {how}")
    saved = dict(info["run_options"])
    known = run_options.names()
    foreign = sorted(k for k, v in saved.items() if k not in known and v is not None)
    if foreign:
        raise RunFolderError(f"{out}/run.json has run option(s) {', '.join(foreign)} that no registered scheme, "
                             f"contact treatment or friction law declares: register it before the restart")
    saved = run_options.complete({k: v for k, v in saved.items() if k in known})
    # a run.json from before the option: its forms had UFL's estimated degrees
    saved["quadrature_degree"] = info["run_options"].get("quadrature_degree", quadrature.ESTIMATED)
    if given.get("T") is not None:
        run_options.check_time(given["T"], saved["dt"], cli)   # a later T: a whole number of the run's steps
    extended = extension(info, given.get("T"), out, cli)
    changed = [f"{k} = {v!r} (the run has {saved.get(k)!r})" for k, v in given.items()
               if k not in (*RESTART_MAY_CHANGE, "T") and v != saved.get(k)]
    if changed:
        raise RunFolderError(f"a restart continues the run as it was started; it cannot change "
                             f"{', '.join(changed)} (only {', '.join(RESTART_MAY_CHANGE)} may change, and T to a "
                             f"later one)")
    saved.update({k: v for k, v in given.items() if k in (*RESTART_MAY_CHANGE, "T") and v is not None})
    saved["quadrature_degree"] = quadrature.of_run(info)      # the degree it used (the automatic choice may change)
    try:
        spec = spec_of_run(info["problem"])
        if problem is not None and resolve(problem).name != spec.name:
            raise RunFolderError(f"{out} holds a {spec.name!r} run, not {resolve(problem).name!r}")
    except ProblemInputError as e:
        raise RunFolderError(f"{out}: {e}") from None
    return RunPlan(spec, spec.values(info["problem"]["args"]), saved, out, restart=True,
                   changed_source=sources or None, extended=extended)


def extension(info: Mapping[str, Any], T: Optional[float], out: Any, cli: bool = False) -> Optional[list[dict[str, Any]]]:
    """run.json's ``extended`` for a restart of the run ``info`` (its run.json) to the final
    time ``T`` (None: the run's own): the run's earlier extensions, and this one when ``T`` is
    later than the run's T (None when there are none). A finished run continues only to a
    later T, and no restart shortens a run.

    Raises:
        RunFolderError: ``T`` is not later than the run's T (or not given for a finished run).
    """
    before = list(info.get("extended") or [])
    recorded = (info.get("run_options") or {}).get("T", info.get("T"))
    finished = info.get("status") == "finished"
    if recorded is None or (T in (None, recorded) and not finished):
        return before or None
    if T is None:
        how = f"--restart {out} --T LATER" if cli else "restart=True with a later T"
        raise RunFolderError(f"{out}: that run is already finished at T = {run_options.num(recorded)}; to extend "
                             f"it: {how}")
    if not T > recorded:
        raise RunFolderError(f"{'--T ' if cli else 'T = '}{run_options.num(T)} is not later than the run's T = "
                             f"{run_options.num(recorded)}: a restart continues a run to its T, or extends it to a "
                             f"later one")
    recorded_options: Mapping[str, Any] = info.get("run_options") or {}
    dt = float(recorded_options["dt"] if "dt" in recorded_options else info["dt"])
    return before + [{"from_T": recorded, "from_step": num_steps(recorded, dt), "to_T": T}]


def source_changes(info: Mapping[str, Any]) -> list[str]:
    """What changed since the run in ``info`` (its run.json) started, in words: its problem file
    (SHA-256 of its bytes) or the package's version; empty when neither did."""
    changed = []
    problem = info.get("problem", {})
    source = problem.get("source")
    if source is not None and Path(source).is_file():
        recorded, now = problem.get("source_sha256"), compat.file_sha256(source)
        if recorded != now:
            changed.append(f"the problem file {source} has changed (SHA-256 {str(recorded)[:12]}... recorded, "
                           f"{now[:12]}... now)" if recorded else
                           f"the problem file {source} may have changed (run.json holds no SHA-256 of it)")
    recorded = info.get("versions", {}).get("sdm_dolfinx")
    if recorded != compat.package_version():
        changed.append(f"sdm_dolfinx is version {compat.package_version()}, the run started with "
                       + (recorded if recorded else "an older one that did not record its version"))
    return changed
