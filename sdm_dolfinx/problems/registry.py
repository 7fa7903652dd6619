"""The one registry of problems: the built-in ones and those declared in a user's file.

A problem file is a Python file defining ``PROBLEM = ProblemSpec(...)`` (see
``docs/add_a_problem.md``); :func:`load_file` imports it and registers its problem, which
then has every command the built-in problems have (``python -m sdm_dolfinx run
--problem-file FILE``). A run records the file's path in ``run.json`` so that ``--restart``,
``energy`` and the pictures find the declaration again.
"""
from __future__ import annotations

import importlib.util
import inspect
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Union

from mpi4py import MPI

from sdm_dolfinx import compat
from sdm_dolfinx.problems.base import Problem, ProblemInputError, ProblemSpec, one_line, user_line

_REGISTRY: dict[str, ProblemSpec] = {}
#: the keys a ProblemSpec's ``defaults`` may hold: the run options a problem may default (those
#: declared ``problem_default`` in :mod:`sdm_dolfinx.run.options`), and the unit of dt and T
DEFAULT_KEYS = ("pair", "scheme", "dt", "T", "material", "time_unit")


def register(spec: ProblemSpec) -> ProblemSpec:
    """Add ``spec`` to the registry (a file's problem may replace one from the same file)."""
    if not isinstance(spec, ProblemSpec):
        raise TypeError(f"register() takes a ProblemSpec, got {type(spec).__name__}")
    _check_build_signature(spec)
    unknown = sorted(set(spec.defaults) - set(DEFAULT_KEYS))
    if unknown:       # a misspelt default would otherwise be ignored without a word
        raise ProblemInputError(f"problem {spec.name!r}: unknown key(s) {', '.join(map(repr, unknown))} in defaults; "
                                f"allowed: {', '.join(DEFAULT_KEYS)}")
    old = _REGISTRY.get(spec.name)
    if old is not None and old.source != spec.source:
        where = old.source or "sdm_dolfinx (built in)"
        raise ProblemInputError(f"a problem called {spec.name!r} is already registered (from {where}); "
                                f"choose another name")
    _REGISTRY[spec.name] = spec
    return spec


def _check_build_signature(spec: ProblemSpec) -> None:
    """``build(comm, **values)`` must take exactly the declared parameters (a misspelt Param
    would otherwise surface only when the problem is built)."""
    try:
        params = list(inspect.signature(spec.build).parameters.values())
    except (TypeError, ValueError):
        return
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return
    takes = {p.name for p in params[1:]}
    declared = {p.name for p in spec.params}
    if takes != declared:
        where = f" ({spec.source})" if spec.source else ""
        missing, extra = sorted(declared - takes), sorted(takes - declared)
        raise ProblemInputError(
            f"problem {spec.name!r}{where}: build(comm, ...) must take exactly the declared parameters"
            + (f"; declared but not taken: {', '.join(missing)}" if missing else "")
            + (f"; taken but not declared: {', '.join(extra)}" if extra else ""))


def names(builtin: bool = False) -> list[str]:
    """The registered problems' names (built-in ones first; ``builtin``: only those)."""
    return [n for n, s in _REGISTRY.items() if not (builtin and s.source)]


def get(name: str) -> ProblemSpec:
    """The registered problem ``name``; ProblemInputError listing the choices otherwise."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ProblemInputError(f"unknown problem {name!r}; registered: {', '.join(_REGISTRY)} "
                                f"(a problem of your own: --problem-file FILE)") from None


def load_file(path: Union[str, Path]) -> ProblemSpec:
    """Import the problem file ``path`` and register its ``PROBLEM``; returns the spec.

    Raises:
        ProblemInputError: no such file, not Python, an error while importing it, or no
            ``PROBLEM = ProblemSpec(...)`` in it (one line each).
    """
    path = Path(path).expanduser().resolve()
    source = str(path)
    for spec in _REGISTRY.values():
        if spec.source == source:
            return spec
    if not path.is_file():
        raise ProblemInputError(f"problem file {path}: no such file")
    if path.suffix != ".py":
        raise ProblemInputError(f"problem file {path}: not a Python file (.py)")
    modname = f"sdm_dolfinx_problem_file_{len(_REGISTRY)}_{path.stem}"
    mod_spec = importlib.util.spec_from_file_location(modname, path)
    if mod_spec is None or mod_spec.loader is None:     # not for a .py file: importlib's own refusal
        raise ProblemInputError(f"problem file {path}: Python cannot import it")
    module = importlib.util.module_from_spec(mod_spec)
    sys.modules[modname] = module
    try:
        mod_spec.loader.exec_module(module)
    except Exception as e:          # the user's code: any error is reported in one line
        sys.modules.pop(modname, None)
        raise ProblemInputError(f"problem file {path}{user_line(e, path)}: {one_line(e)}") from None
    declared = getattr(module, "PROBLEM", None)
    if not isinstance(declared, ProblemSpec):
        raise ProblemInputError(f"problem file {path}: defines no PROBLEM = ProblemSpec(...) "
                                f"(see docs/add_a_problem.md)")
    declared.source, declared.source_sha256 = source, compat.file_sha256(path)
    return register(declared)


def resolve(problem: Union[ProblemSpec, str, Path]) -> ProblemSpec:
    """A ProblemSpec from a spec, a registered name or the path of a problem file (``.py``)."""
    if isinstance(problem, ProblemSpec):
        return problem
    if str(problem).endswith(".py"):
        return load_file(problem)
    return get(str(problem))


def spec_of_run(described: Mapping[str, Any]) -> ProblemSpec:
    """The spec that built a run, from its ``run.json`` ``problem`` entry (name, source)."""
    source = described.get("source")
    if source:
        return load_file(source)
    return get(described["name"])


def rebuild(described: Mapping[str, Any], comm: MPI.Comm = MPI.COMM_WORLD) -> Problem:
    """The Problem of a finished run, from its ``run.json`` ``problem`` entry.

    Raises:
        ProblemInputError: the run's problem is not declared (built by hand through the
            API, no ``args`` recorded) or its declaration cannot be found.
    """
    if "args" not in described:
        raise ProblemInputError(f"the run's problem {described.get('name')!r} was built without a declaration "
                                f"(no 'args' in run.json): declare it with a ProblemSpec to post-process it "
                                f"(docs/add_a_problem.md)")
    spec = spec_of_run(described)
    return spec.problem(comm, **described["args"])
