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
import math
import os
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.method import quadrature
from sdm_dolfinx.contact import friction
from sdm_dolfinx import schemes
from sdm_dolfinx.method.pairs import get_pair
from sdm_dolfinx.problems import ProblemInputError, resolve, spec_of_run
from sdm_dolfinx.io.folder import RunFolderError, check_out, read_info
from sdm_dolfinx.run.result import num_steps
from sdm_dolfinx.run.simulate import simulate
from sdm_dolfinx.solvers import LINEAR_STRATEGIES, VI_SOLVERS
from sdm_dolfinx.solvers.memory import per_rank, run_bytes

#: the run options and their defaults where the problem declares none
RUN_DEFAULTS = {"pair": "P1+/P0", "scheme": "midpoint", "dt": 1e-3, "T": 0.8, "mass": None, "vi_solver": "ssn",
                "linear": "auto", "write_every": None, "checkpoint_every": None, "quadrature_degree": None,
                "friction": None, "mu": None, "tresca_threshold": None, "constrain": "vertices", "contact": "exact",
                "penalty": None, "nitsche_theta": None, "nitsche_gamma0": None, "hht_alpha": None,
                "restitution": None}
#: where the constraint K^h acts (:class:`~sdm_dolfinx.method.discretisation.Discretisation`)
CONSTRAIN = ("vertices", "nodes")
#: the contact treatments (:mod:`sdm_dolfinx.contact`)
CONTACTS = ("exact", "penalty", "nitsche")
#: method parameters: (the option that uses them, its value, the check, what it must be)
METHOD_PARAMETERS = {
    "hht_alpha": ("scheme", "hht", lambda v: -1 / 3 <= v <= 0, "a number in [-1/3, 0]"),
    "restitution": ("scheme", "paoli-schatzman", lambda v: 0 <= v <= 1, "a number in [0, 1]"),
    "penalty": ("contact", "penalty", lambda v: 0 < v < float("inf"), "a positive number"),
    "nitsche_theta": ("contact", "nitsche", lambda v: v in (-1, 0, 1), "-1, 0 or 1"),
    "nitsche_gamma0": ("contact", "nitsche", lambda v: 0 < v < float("inf"), "a positive number"),
}
#: options a restart may change (the others are the run's)
RESTART_MAY_CHANGE = ("checkpoint_every",)
#: the longest run accepted (T / dt): ~100 bytes of time series per step in memory
MAX_STEPS = 1e7
#: T must be a whole number of steps of dt, to this relative tolerance
STEP_RTOL = 1e-9

# ---- memory estimates (measured with the run's maxrss on dolfinx 0.5.2 / PETSc 3.18, 1 rank,
# membrane N = 100 to 400 and disc levels 4-5, default solver; see estimate_memory)
#: bytes per dof of W^h and per component of u, by pair (the run's matrices, factorisation
#: or AMG hierarchy, vectors); the P?/P1 pairs pay for the denser M = B^T C^-1 B
BYTES_PER_DOF = {"P1+/P0": 1300, "P1/P0": 2200, "P1/P1": 1700, "P1+/P1": 3000, "P2/P1": 4000, "P2/P2": 1400}
#: for a pair not measured
DEFAULT_BYTES_PER_DOF = 4000
#: an inf-sup inspection (SuperLU of B B^T, ARPACK), any pair
INSPECT_BYTES_PER_DOF = 3000
#: solvers that factorise a matrix of K's size at every iteration need about twice as much
#: (measured: --linear lu, P2/P1, N = 100: 6.8 kB per dof)
REFACTORISING = 2.0
#: one process before any mesh: Python, dolfinx, PETSc, gmsh (measured 100-150 MB)
BYTES_PER_PROCESS = 150e6


class RunInputError(SdmError, ValueError):
    """A run's inputs are refused (one line; nothing was written)."""


@dataclass
class RunPlan:
    """A checked run: the problem's declaration, its parameter values and the run options."""
    spec: object
    params: dict
    options: dict
    out: object = None
    restart: bool = False
    #: what the folder held when checked ({"run_id": ...}), checked again under the run's lock
    folder_seen: object = None

    @property
    def steps(self):
        return num_steps(self.options["T"], self.options["dt"])

    def run(self, comm=MPI.COMM_WORLD, progress=False, handle_signals=False, on_step=None, petsc_options=None,
            extra_info=None):
        """Build the problem and run it (see :func:`sdm_dolfinx.run.simulate.simulate`)."""
        problem = self.spec.problem(comm, **self.params)
        return simulate(problem, out=self.out, restart=self.restart, progress=progress,
                        handle_signals=handle_signals, on_step=on_step, petsc_options=petsc_options,
                        extra_info=extra_info, folder_seen=self.folder_seen, **self.options)


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
    check_memory(spec, values, [opts["pair"]], comm, cli, options=opts, steps=num_steps(opts["T"], opts["dt"]))
    seen = None
    if out is not None:
        check_out_name(out, cli)
        try:
            seen = check_out(Path(out), overwrite, comm)
        except RunFolderError as e:
            raise RunInputError(str(e)) from None
    return RunPlan(spec, values, opts, out, folder_seen={"run_id": seen} if out is not None else None)


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
        else:
            errors += _check_whole_steps(o["T"], o["dt"])
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
    errors += _check_method(o)
    errors += quadrature.check(o["quadrature_degree"])
    errors += friction.check(o["friction"], o["mu"], o["tresca_threshold"])
    errors += friction.check_solver(o["friction"], o["vi_solver"], o["linear"])
    if errors:
        raise RunInputError("; ".join(errors))


def _check_method(o):
    """Messages for the method options: a value out of range, or a parameter given to a scheme or
    contact treatment that does not use it (it would be ignored without a word)."""
    errors = []
    if o["constrain"] not in CONSTRAIN:
        errors.append(f"unknown constrain {o['constrain']!r}; choose one of {', '.join(CONSTRAIN)}")
    if o["contact"] not in CONTACTS:
        errors.append(f"unknown contact {o['contact']!r}; choose one of {', '.join(CONTACTS)}")
    for k, (owner, value, ok, what) in METHOD_PARAMETERS.items():
        v = o[k]
        if v is None:
            continue
        if o[owner] != value:
            errors.append(f"{k} is a parameter of {owner} {value}, not of {owner} {o[owner]}: remove it or "
                          f"choose {owner} {value}")
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not ok(v):
            errors.append(f"{k} must be {what} (got {v!r})")
    stateful = getattr(schemes.get(o["scheme"]), "stateful", False) if o["scheme"] in schemes.names() else False
    if stateful and o["checkpoint_every"] is not None:
        errors.append(f"checkpoint_every must be left out with scheme {o['scheme']}: it keeps state between steps "
                      f"that a checkpoint does not hold (it cannot restart)")
    return errors


def _check_whole_steps(T, dt):
    """A message when T is not a whole number of steps of dt (relative tolerance
    :data:`STEP_RTOL`): the run would silently stop short of T. The steps are counted as the
    run counts them (:func:`~sdm_dolfinx.run.result.num_steps`), so T = 0.02, dt = 1e-4
    (200.00000000000003 steps in floating point) is 200 steps and accepted."""
    n = num_steps(T, dt)
    if abs(n * dt - T) <= STEP_RTOL * T:
        return []
    return [f"T = {_num(T)} is not a multiple of dt = {_num(dt)}: {n} steps end at t = {_num(n * dt)}; give "
            f"T = {_num(n * dt)} or {_num((n + 1) * dt)}"]


def _num(x):
    """A time for messages: 0.009, not 0.009000000000000001."""
    return f"{x:.12g}"


def check_out_name(out, cli=False):
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


def _existing_parent(path):
    while not path.exists():
        path = path.parent
    return path


# ------------------------------------------------------------------------------- memory
def available_memory(comm=MPI.COMM_WORLD):
    """The machine's available memory in bytes (``MemAvailable`` of /proc/meminfo, read on
    rank 0), or None where there is no /proc/meminfo."""
    def read():
        try:
            with open("/proc/meminfo") as fh:
                for line in fh:
                    if line.startswith("MemAvailable:"):
                        return float(line.split()[1]) * 1024.0
        except (OSError, ValueError, IndexError):
            return None
        return None
    return comm.bcast(read() if comm.rank == 0 else None, root=0)


def _lagrange_dofs(family, degree, counts):
    """Nodes of one component of a Lagrange (``P``), P1 + bubble (``P+``) or DG0 space on a
    triangle mesh with these entity counts."""
    v, e, c = counts["vertices"], counts["edges"], counts["cells"]
    if family == "P+":
        return v + c
    if degree == 0:
        return c
    return v + (degree - 1) * e + (degree - 1) * (degree - 2) // 2 * c


def estimate_memory(spec, values, pair, options=None, steps=0, ranks=1, inspect=False):
    """(bytes, dim W^h) that a run (or with ``inspect`` an inf-sup inspection) of ``spec``
    with parameter ``values`` and ``pair`` needs, or None when the problem declares no
    estimate (``spec.estimate(values)`` -> mesh entity counts, see the membrane).

    A model, not a measurement: bytes per dof of W^h (:data:`BYTES_PER_DOF`, per component
    of u: a vector problem's rows have twice the nonzeros), doubled for solvers that refactorise
    (:data:`REFACTORISING`), plus :data:`BYTES_PER_PROCESS` per rank and ~100 bytes per step of
    time series. Measured runs needed 0.75-0.9 times the estimate (membrane N = 100-400, every pair;
    disc levels 4-5; inspections 0.75). In 3-D (``counts["dim"]``, or a 3-component u) the
    factorisation's fill grows as n^(4/3): :func:`sdm_dolfinx.solvers.memory.run_bytes`, a fit of
    the ball's measured peak RSS (levels 1-4), of the factorised or the iterative strategy
    (``auto``: the smaller, as ``auto`` goes iterative when the factorisation does not fit); on
    several ranks each holds :func:`~sdm_dolfinx.solvers.memory.per_rank` of it (measured: not half
    on 2 ranks).
    """
    estimate = getattr(spec, "estimate", None)
    counts = estimate(values) if estimate is not None else None
    if counts is None:
        return None
    pair = get_pair(pair) if isinstance(pair, str) else pair
    vs = counts.get("value_size", 1)
    dim_w = vs * _lagrange_dofs(*pair.w, counts)
    dim = counts.get("dim", 3 if vs == 3 else 2)
    if not inspect and dim >= 3:     # 3-D: the factor's fill grows faster than n (solvers.memory)
        o = options or {}
        linear = o.get("linear", "auto")
        factorised = run_bytes(dim_w, dim, factorised=True)
        if o.get("vi_solver", "ssn") != "ssn" or linear == "lu":
            need = REFACTORISING * factorised
        elif linear in ("amg", "cg-amg", "cg-gamg"):
            need = run_bytes(dim_w, dim, factorised=False)
        elif linear == "auto":           # auto takes cg-gamg when the factorisation does not fit
            need = min(factorised, run_bytes(dim_w, dim, factorised=False))
        else:
            need = factorised
        return per_rank(need, ranks) * ranks + BYTES_PER_PROCESS * ranks + 100.0 * steps, dim_w
    if inspect:
        per_dof = INSPECT_BYTES_PER_DOF
    else:
        per_dof = BYTES_PER_DOF.get(pair.name, DEFAULT_BYTES_PER_DOF) * vs
        o = options or {}
        if o.get("linear") == "lu" or o.get("vi_solver", "ssn") != "ssn":
            per_dof *= REFACTORISING
    return float(per_dof) * dim_w + BYTES_PER_PROCESS * ranks + 100.0 * steps, dim_w


def check_memory(spec, values, pairs, comm=MPI.COMM_WORLD, cli=False, options=None, steps=0, inspect=False):
    """RunInputError when the estimated memory (:func:`estimate_memory`, the largest over
    ``pairs``) exceeds the machine's available memory: "--N 4500 needs about 79 GB (dim W^h =
    6.1e+07 with P1+/P0), this machine has 21 GB available"."""
    worst = None
    for pair in pairs:
        try:
            est = estimate_memory(spec, values, pair, options, steps, comm.size, inspect)
        except ValueError:          # an unknown pair: check_options says so
            continue
        if est is not None and (worst is None or est[0] > worst[0]):
            worst = (est[0], est[1], pair if isinstance(pair, str) else pair.name)
    if worst is None:
        return
    avail = available_memory(comm)
    if avail is None or worst[0] <= avail:
        return
    by = getattr(spec, "estimate")(values).get("by", ())
    what = " ".join(f"--{spec.param(k).option} {_value(values[k])}" if cli else f"{k} = {_value(values[k])}"
                    for k in by) or f"problem {spec.name}"
    raise RunInputError(f"{what} needs about {_gb(worst[0])} GB (dim W^h = {worst[1]:.2g} with {worst[2]}), this "
                        f"machine has {_gb(avail)} GB available")


def _value(v):
    return " ".join(map(str, v)) if isinstance(v, (tuple, list)) else str(v)


def _gb(b):
    """Bytes in GB for messages: 79, 2.4, or 1e+300."""
    g = b / 1e9
    if not math.isfinite(g) or g >= 1e6:
        return f"{g:.2g}"
    return f"{g:.0f}" if g >= 10 else f"{g:.2g}"


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
    # a run.json from before the option: its forms had UFL's estimated degrees
    saved.setdefault("quadrature_degree", quadrature.ESTIMATED)
    changed = [f"{k} = {v!r} (the run has {saved.get(k)!r})" for k, v in options.items()
               if k not in RESTART_MAY_CHANGE and v != saved.get(k)]
    if changed:
        raise RunFolderError(f"a restart continues the run as it was started; it cannot change "
                             f"{', '.join(changed)} (only {', '.join(RESTART_MAY_CHANGE)} may change)")
    saved.update({k: v for k, v in options.items() if k in RESTART_MAY_CHANGE and v is not None})
    saved["quadrature_degree"] = quadrature.of_run(info)      # the degree it used (the automatic choice may change)
    try:
        spec = spec_of_run(info["problem"])
    except ProblemInputError as e:
        raise RunFolderError(f"{out}: {e}") from None
    return RunPlan(spec, spec.values(info["problem"]["args"]), saved, out, restart=True)
