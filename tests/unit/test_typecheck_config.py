"""The type check's configuration (``pyproject.toml``'s ``[tool.mypy]``, run by ``make typecheck``)
checks what docs/testing.md says it checks.

mypy's own ``strict = true`` is global-only: in an override it silently turns strict mode on for
every module, so the override of the public modules spells out the flags of ``--strict``. These
tests compare that list with what ``--strict`` sets in the mypy installed (a new flag in a new
mypy would otherwise be missing without a word), check that every module named exists (mypy only
notes an override that matches nothing) and that every public name of ``sdm_dolfinx`` is defined
in a strictly checked module, and that the package ships its ``py.typed`` marker (PEP 561).
"""
import importlib
import inspect
import sys
from pathlib import Path

import pytest

import sdm_dolfinx

ROOT = Path(__file__).resolve().parents[2]

if sys.version_info >= (3, 11):
    import tomllib
else:                               # pragma: no cover
    tomllib = pytest.importorskip("tomli")

CONFIG = tomllib.loads((ROOT / "pyproject.toml").read_text())
MYPY = CONFIG["tool"]["mypy"]
#: the override that checks the public modules strictly (the one that sets disallow_untyped_defs)
STRICT = next(o for o in MYPY["overrides"] if o.get("disallow_untyped_defs"))


def _module_file(name):
    base = ROOT / name.replace(".", "/")
    return base.with_suffix(".py") if base.with_suffix(".py").is_file() else base / "__init__.py"


def test_strict_modules_exist():
    missing = [m for m in STRICT["module"] if not _module_file(m).is_file()]
    assert not missing, f"pyproject.toml's strict override names modules that do not exist: {missing}"
    assert not any(m.endswith("*") for m in STRICT["module"]), "name each public module (a pattern hides new ones)"


def test_the_public_modules_get_every_flag_of_strict():
    pytest.importorskip("mypy", reason="mypy is installed by scripts/setup.sh (make typecheck)")
    from mypy.main import process_options
    from mypy.options import PER_MODULE_OPTIONS
    _, plain = process_options(["--config-file=", __file__])         # only the options are compared
    _, strict = process_options(["--strict", "--config-file=", __file__])
    names = [n for n in dir(plain) if not n.startswith("_") and not callable(getattr(plain, n))]
    flags = {n: getattr(strict, n) for n in names if getattr(plain, n) != getattr(strict, n)}
    assert "disallow_untyped_defs" in flags and "warn_return_any" in flags
    assert "strict" not in STRICT, "strict = true in an override applies to every module: list the flags"
    per_module = {n: v for n, v in flags.items() if n in PER_MODULE_OPTIONS}
    assert {n: STRICT.get(n) for n in per_module} == per_module
    global_only = {n: v for n, v in flags.items() if n not in PER_MODULE_OPTIONS}
    assert {n: MYPY.get(n) for n in global_only} == global_only


def test_public_names_are_defined_in_strict_modules():
    """What ``from sdm_dolfinx import ...`` gives (functions, classes) is annotated and checked
    strictly; exceptions (classes with a message) and the problem modules are not listed."""
    strict = set(STRICT["module"])
    loose = []
    for name in sdm_dolfinx.__all__:
        obj = getattr(sdm_dolfinx, name)
        if inspect.ismodule(obj) or (inspect.isclass(obj) and issubclass(obj, BaseException)):
            continue
        if obj.__module__ not in strict:
            loose.append(f"{name} ({obj.__module__})")
    assert not loose, f"public names defined outside the strictly checked modules: {loose}"
    for kind in ("problems", "run"):            # packages users import from: explicit re-exports
        mod = importlib.import_module(f"sdm_dolfinx.{kind}")
        assert f"sdm_dolfinx.{kind}" in strict and all(hasattr(mod, n) for n in mod.__all__)


def test_the_package_ships_its_py_typed_marker():
    assert (ROOT / "sdm_dolfinx" / "py.typed").is_file()
    assert "py.typed" in CONFIG["tool"]["setuptools"]["package-data"]["sdm_dolfinx"]
