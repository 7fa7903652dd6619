"""The package's shape (docs/architecture.md): imports point one way between the layers, no folder
is a catch-all, every error derives from one base, and modules and functions stay small enough to
read in one sitting.

Imports are read from the source with ``ast`` (function-level imports included), so a cycle
hidden inside a function is caught as well as one at module level.
"""
import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "sdm_dolfinx"

#: the layers, bottom first: a module may import its own layer's package and the ones below
LAYERS = {"compat": 0, "mpiutil": 0, "errors": 0, "params": 0.5, "obstacles": 0.75, "materials": 0.8, "problems": 1, "solvers": 1, "method": 2, "schemes": 3,
          "contact": 3, "io": 4, "run": 5, "analysis": 6, "post": 6, "study": 7, "paper": 8, "compare": 8,
          "validation": 8, "report": 9, "cli": 10}
#: the package's entry points, which may import any layer (``__init__`` re-exports the public API
#: and must not import the CLI; ``__main__`` is the CLI's entry)
FACADE = {"__init__": 9, "__main__": 10}
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80
#: a function longer than MAX_FUNCTION_LINES carries this marker in a comment on its ``def``
#: line or the line above, followed by the reason
LONG_MARKER = "long:"


def modules():
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def layer_of(path):
    rel = path.relative_to(PACKAGE)
    top = rel.parts[0].removesuffix(".py")
    if top in FACADE:
        return top, FACADE[top]
    return top, LAYERS[top]


def imported(path):
    """(line, top-level package part) of every import of sdm_dolfinx in the file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = path.relative_to(PACKAGE.parent).with_suffix("").parts[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                if parts[0] == "sdm_dolfinx":
                    yield node.lineno, parts[1] if len(parts) > 1 else None
        elif isinstance(node, ast.ImportFrom):
            if node.level:                                 # relative: resolve against the package
                base = list(package[:len(package) - node.level + 1])
                parts = base + (node.module.split(".") if node.module else [])
            else:
                parts = (node.module or "").split(".")
            if parts[0] != "sdm_dolfinx":
                continue
            if len(parts) > 1:
                yield node.lineno, parts[1]
            else:                                          # from sdm_dolfinx import x, y
                for a in node.names:
                    yield node.lineno, a.name


def test_every_module_belongs_to_a_layer():
    unknown = [str(p.relative_to(PACKAGE)) for p in modules()
               if p.relative_to(PACKAGE).parts[0].removesuffix(".py") not in {**LAYERS, **FACADE}]
    assert not unknown, f"modules outside the layers of docs/architecture.md: {unknown}"


def test_imports_point_down_only():
    """compat, mpiutil, errors <- problems, solvers <- method <- schemes, contact <- io <- run <- analysis, post
    <- study <- paper, compare, validation <- report <- cli; nothing imports cli."""
    bad = []
    for path in modules():
        name, level = layer_of(path)
        for line, target in imported(path):
            if target is None or target in FACADE:
                if name not in FACADE and target == "__init__":
                    bad.append(f"{path.relative_to(PACKAGE)}:{line} imports the package facade")
                continue
            t = LAYERS.get(target)
            if t is None:
                bad.append(f"{path.relative_to(PACKAGE)}:{line} imports unknown sdm_dolfinx.{target}")
            elif target == "cli" and name not in ("cli", "__main__"):
                bad.append(f"{path.relative_to(PACKAGE)}:{line} imports the CLI")
            elif target != name and t >= level and name not in FACADE:
                bad.append(f"{path.relative_to(PACKAGE)}:{line} ({name}, layer {level}) imports {target} "
                           f"(layer {t})")
    assert not bad, "imports against the layers:\n" + "\n".join(bad)


def test_the_checker_sees_function_level_imports(tmp_path):
    """The checker itself: an import inside a function is found (an upward one would be reported)."""
    src = tmp_path / "sdm_dolfinx" / "problems" / "x.py"
    src.parent.mkdir(parents=True)
    src.write_text("def f():\n    from sdm_dolfinx.cli import main\n    from ..run import launch\n")
    global PACKAGE
    saved, PACKAGE = PACKAGE, tmp_path / "sdm_dolfinx"
    try:
        assert list(imported(src)) == [(2, "cli"), (3, "run")]
    finally:
        PACKAGE = saved


def _module_name(path):
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _module_imports(path, known):
    """The modules of sdm_dolfinx (names in ``known``) that ``path`` imports, function-level ones included."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            targets = [f"{module}.{a.name}" if f"{module}.{a.name}" in known else module for a in node.names]
        else:
            continue
        yield from (t for t in targets if t in known and t != name)


def test_no_import_cycles():
    """No module imports (directly or through others) one that imports it back, within a layer
    too (the layer check cannot see paper.study <-> paper.friction_study)."""
    paths = {_module_name(p): p for p in modules()}
    graph = {m: set(_module_imports(p, paths)) for m, p in paths.items()}
    cycles = []
    for start in graph:                        # a path from each module back to itself
        stack, seen = [(start, [start])], set()
        while stack:
            node, trail = stack.pop()
            for nxt in graph[node]:
                if nxt == start:
                    cycles.append(" -> ".join(trail + [start]))
                elif nxt not in seen:
                    seen.add(nxt)
                    stack.append((nxt, trail + [nxt]))
    assert not cycles, "import cycles:\n" + "\n".join(sorted(set(cycles))[:10])


#: no folder of the package holds more than this share of its lines (folders by concept, none a catch-all)
MAX_FOLDER_SHARE = 0.15


def test_no_folder_is_a_catch_all():
    """Folders by concept: none holds over 15 % of the package's lines (subfolders counted with their folder)."""
    lines = {p: len(p.read_text().splitlines()) for p in modules()}
    total = sum(lines.values())
    folders = {}
    for p, n in lines.items():
        rel = p.relative_to(PACKAGE)
        if len(rel.parts) > 1:
            folders[rel.parts[0]] = folders.get(rel.parts[0], 0) + n
    big = {f: f"{n / total:.1%}" for f, n in folders.items() if n > MAX_FOLDER_SHARE * total}
    assert len(folders) >= 10 and not big, f"folders over {MAX_FOLDER_SHARE:.0%} of {total} lines: {big}"


def test_modules_are_small():
    big = [f"{p.relative_to(PACKAGE)}: {n} lines" for p in modules()
           if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES]
    assert not big, f"modules over {MAX_MODULE_LINES} lines: {big}"


def test_long_functions_say_why():
    long_ones = []
    for p in modules():
        lines = p.read_text().splitlines()
        for node in ast.walk(ast.parse("\n".join(lines))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                first = (node.decorator_list[0].lineno if node.decorator_list else node.lineno) - 1
                context = " ".join(lines[max(first - 1, 0):node.lineno])
                if n > MAX_FUNCTION_LINES and LONG_MARKER not in context:
                    long_ones.append(f"{p.relative_to(PACKAGE)}:{node.lineno} {node.name}: {n} lines")
    assert not long_ones, (f"functions over {MAX_FUNCTION_LINES} lines without a '# {LONG_MARKER} <reason>' "
                           f"comment: {long_ones}")


@pytest.mark.parametrize("registry,module", [("problems", "sdm_dolfinx.problems"),
                                             ("pairs", "sdm_dolfinx.method.pairs"),
                                             ("schemes", "sdm_dolfinx.schemes"),
                                             ("contact", "sdm_dolfinx.contact"),
                                             ("solvers", "sdm_dolfinx.solvers")])
def test_registries_have_a_register_function(registry, module):
    """Each extension point is a registry with a register() (docs/architecture.md)."""
    import importlib
    mod = importlib.import_module(module)
    assert callable(getattr(mod, "register", None)), f"{module} has no register()"


def test_every_error_derives_from_sdm_error():
    """One exception base: every exception class the package defines (warnings aside) is an
    :class:`sdm_dolfinx.errors.SdmError`, so ``except SdmError`` catches every one-line error."""
    import importlib
    import inspect as _inspect
    from sdm_dolfinx.errors import SdmError
    found, bad = 0, []
    for path in modules():
        if path.name in ("__main__.py", "pyvista_scene.py"):
            continue
        mod = importlib.import_module(_module_name(path))
        for name, cls in vars(mod).items():
            if (_inspect.isclass(cls) and issubclass(cls, BaseException) and cls.__module__ == mod.__name__
                    and not issubclass(cls, Warning)):
                found += 1
                if not issubclass(cls, SdmError):
                    bad.append(f"{mod.__name__}.{name}")
    assert found >= 15 and not bad, f"exceptions without the SdmError base: {bad}"
