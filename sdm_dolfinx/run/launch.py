"""Running a declared problem by name: the one Python entry point of the command line, the
paper's study and the demos.

    from sdm_dolfinx.run import launch
    result = launch("membrane", {"N": 20}, out="output/m20", pair="P2/P1", dt=5e-4)
    result = launch("my_block.py", {"h": 2.0}, out="output/block")     # a problem file
    result = launch(out="output/m20", restart=True)                     # continue a run

Every input is checked before anything is written (:class:`RunInputError`, one line); the
run's problem, parameters and options are recorded in ``run.json``, so a restart, the
``energy`` command and the pictures rebuild the same run from the folder alone.
"""
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx.method import schemes
from sdm_dolfinx.method.pairs import get_pair
from sdm_dolfinx.problems import ProblemInputError, resolve, spec_of_run
from sdm_dolfinx.run.folder import RunFolderError, check_out, read_info
from sdm_dolfinx.run.result import num_steps
from sdm_dolfinx.run.simulate import simulate
from sdm_dolfinx.solvers import LINEAR_STRATEGIES, VI_SOLVERS

#: the run options and their defaults where the problem declares none
RUN_DEFAULTS = {"pair": "P1+/P0", "scheme": "midpoint", "dt": 1e-3, "T": 0.8, "mass": None, "vi_solver": "ssn",
                "linear": "auto", "write_every": None, "checkpoint_every": None}
#: options a restart may change (the others are the run's)
RESTART_MAY_CHANGE = ("checkpoint_every",)
#: the longest run accepted (T / dt): ~100 bytes of time series per step in memory
MAX_STEPS = 1e7


class RunInputError(ValueError):
    """A run's inputs are refused (one line; nothing was written)."""


@dataclass
class RunPlan:
    """A checked run: the problem's declaration, its parameter values and the run options."""
    spec: object
    params: dict
    options: dict
    out: object = None
    restart: bool = False

    @property
    def steps(self):
        return num_steps(self.options["T"], self.options["dt"])

    def run(self, comm=MPI.COMM_WORLD, progress=False, handle_signals=False, on_step=None, petsc_options=None,
            extra_info=None):
        """Build the problem and run it (see :func:`sdm_dolfinx.run.simulate.simulate`)."""
        problem = self.spec.problem(comm, **self.params)
        return simulate(problem, out=self.out, restart=self.restart, progress=progress,
                        handle_signals=handle_signals, on_step=on_step, petsc_options=petsc_options,
                        extra_info=extra_info, **self.options)


def plan(problem=None, params=None, *, out=None, overwrite=False, restart=False, comm=MPI.COMM_WORLD, cli=False,
         **options):
    """Check a run's inputs and the output folder; returns a :class:`RunPlan` (nothing written).

    Args:
        problem: a registered name, a :class:`~sdm_dolfinx.problems.ProblemSpec` or the path
            of a problem file (not needed with ``restart``).
        params: the problem's parameter values (its declared names; the rest at defaults).
        out: the output folder (None: nothing written).
        overwrite: replace a run already in ``out``.
        restart: continue the run in ``out`` (problem, parameters and options from its
            ``run.json``; options given must be the run's, except :data:`RESTART_MAY_CHANGE`).
        cli: name parameters ``--option`` in messages (the command line's spelling).
        options: run options (:data:`RUN_DEFAULTS`; ``pair``, ``scheme``, ``dt`` and ``T``
            default to the problem's declared defaults).

    Raises:
        RunInputError: any refused input, with every reason.
    """
    unknown = sorted(set(options) - set(RUN_DEFAULTS))
    if unknown:
        raise RunInputError(f"unknown run option(s) {', '.join(unknown)}; the run options: {', '.join(RUN_DEFAULTS)}")
    try:
        if restart:
            return _restart_plan(out, options, comm)
        spec = resolve(problem)
        values = spec.values(params, cli=cli)
    except (ProblemInputError, RunFolderError) as e:
        raise RunInputError(str(e)) from None
    opts = {**RUN_DEFAULTS, **{k: v for k, v in spec.defaults.items() if k in RUN_DEFAULTS}, **options}
    check_options(opts)
    if out is not None:
        try:
            check_out(Path(out), overwrite, comm)
        except RunFolderError as e:
            raise RunInputError(str(e)) from None
    return RunPlan(spec, values, opts, out)


def launch(problem=None, params=None, *, out=None, overwrite=False, restart=False, comm=MPI.COMM_WORLD,
           progress=False, handle_signals=False, on_step=None, petsc_options=None, **options):
    """:func:`plan` then :meth:`RunPlan.run`: run a declared problem; returns the
    :class:`~sdm_dolfinx.run.result.Result`."""
    p = plan(problem, params, out=out, overwrite=overwrite, restart=restart, comm=comm, **options)
    return p.run(comm, progress=progress, handle_signals=handle_signals, on_step=on_step,
                 petsc_options=petsc_options)


def check_options(o):
    """Messages for run options out of range, joined in one RunInputError."""
    errors = []
    for k in ("dt", "T"):
        if not (isinstance(o[k], (int, float)) and 0 < o[k] < float("inf")):
            errors.append(f"{k} must be a positive finite number (got {o[k]!r})")
    if not errors:
        if o["T"] < o["dt"]:
            errors.append(f"T ({o['T']}) must be >= dt ({o['dt']})")
        elif o["T"] / o["dt"] > MAX_STEPS:
            errors.append(f"T / dt = {o['T'] / o['dt']:.3g} steps: at most {MAX_STEPS:.0e} (the time series "
                          f"alone would take {o['T'] / o['dt'] * 100 / 1e9:.3g} GB)")
    for k in ("write_every", "checkpoint_every"):
        if o[k] is not None and (not isinstance(o[k], int) or o[k] < 1):
            errors.append(f"{k} must be an integer >= 1 (got {o[k]!r})")
    try:
        pair = get_pair(o["pair"]) if isinstance(o["pair"], str) else o["pair"]
        if o["mass"] is not None and o["mass"] not in pair.allowed_masses():
            errors.append(f"mass {o['mass']} is not available for {pair.name}; choose "
                          f"{', '.join(pair.allowed_masses())}")
    except ValueError as e:
        errors.append(str(e))
    if o["scheme"] not in schemes.names():
        errors.append(f"unknown scheme {o['scheme']!r}; choose one of {', '.join(schemes.names())}")
    if o["vi_solver"] not in VI_SOLVERS:
        errors.append(f"unknown step solver {o['vi_solver']!r}; choose one of {', '.join(VI_SOLVERS)}")
    if o["linear"] not in LINEAR_STRATEGIES:
        errors.append(f"unknown linear strategy {o['linear']!r}; choose one of {', '.join(LINEAR_STRATEGIES)}")
    if errors:
        raise RunInputError("; ".join(errors))


def _restart_plan(out, options, comm):
    """The plan of the run in ``out`` to be continued."""
    if out is None:
        raise RunFolderError("a restart needs the run's folder (out)")
    info = read_info(out, comm)
    if info.get("status") == "finished":
        raise RunFolderError(f"{out}: that run is already finished")
    if "run_options" not in info or "args" not in info.get("problem", {}):
        raise RunFolderError(f"{out}/run.json does not say how the run was started (written by an older version "
                             f"or by a problem built by hand): it cannot be continued")
    saved = dict(info["run_options"])
    changed = [f"{k} = {v!r} (the run has {saved.get(k)!r})" for k, v in options.items()
               if k not in RESTART_MAY_CHANGE and v != saved.get(k)]
    if changed:
        raise RunFolderError(f"a restart continues the run as it was started; it cannot change "
                             f"{', '.join(changed)} (only {', '.join(RESTART_MAY_CHANGE)} may change)")
    saved.update({k: v for k, v in options.items() if k in RESTART_MAY_CHANGE and v is not None})
    try:
        spec = spec_of_run(info["problem"])
    except ProblemInputError as e:
        raise RunFolderError(f"{out}: {e}") from None
    return RunPlan(spec, spec.values(info["problem"]["args"]), saved, out, restart=True)
