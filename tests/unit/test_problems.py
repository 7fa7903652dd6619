"""sdm_dolfinx.problems without a time loop: parameter declarations (Param), their checking
(ProblemSpec.values), the registry (get, names, register, load_file) and the rebuilding of a
run's problem from its run.json entry (rebuild).

The expectations are the declarations' documented contracts (docstrings of base.py and
registry.py), not outputs copied from the code: e.g. a strict lower bound refuses the bound
itself, an integer parameter refuses 2.5 and True, a value that run.json stores as JSON must
rebuild the same Problem. Everything runs on 1 and 2 ranks (files are written on rank 0 into
``mpi_tmp_path`` and read by every rank after a barrier).
"""
import json
import math
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import problems
from sdm_dolfinx.problems import Param, Problem, ProblemInputError, ProblemSpec, disc, membrane, registry

COMM = MPI.COMM_WORLD


def one_line(exc):
    """The message of a refused input must be one line (the CLI prints it as is)."""
    msg = str(exc.value)
    assert msg and "\n" not in msg, msg
    return msg


# ------------------------------------------------------------------------------ Param
def test_param_kind_from_default_and_type():
    # the kind follows the declared type, else the default's type; None defaults are floats
    assert Param("n", 3, "h").kind is int
    assert Param("x", 1.5, "h").kind is float
    assert Param("b", True, "h").kind is bool            # bool before int: True is an int in Python
    assert Param("p", (0.0, 1.0), "h").kind == "point"
    assert Param("h", None, "h").kind is float
    assert Param("f", None, "h", type=Path).kind is Path


def test_param_inclusive_and_strict_lower_bound():
    inclusive = Param("height", 1.0, "h", unit="mm", low=0.0)
    strict = Param("radius", 1.0, "h", unit="mm", low=0.0, low_strict=True)
    assert inclusive.check(0.0, "height") == []          # >= 0 admits the bound itself
    assert strict.check(1e-300, "radius") == []          # > 0 admits any positive number
    msg = strict.check(0.0, "radius")
    assert len(msg) == 1 and "> 0" in msg[0] and ">=" not in msg[0] and "mm" in msg[0]
    msg = inclusive.check(-1e-12, "height")
    assert len(msg) == 1 and ">= 0" in msg[0]


def test_param_upper_bound_is_inclusive():
    p = Param("nu", 0.3, "h", low=0.0, high=0.49)
    assert p.check(0.49, "nu") == []
    msg = p.check(0.4900001, "nu")
    assert len(msg) == 1 and "<= 0.49" in msg[0]


def test_param_integer_refuses_fractions_and_bools():
    p = Param("N", 10, "h", type=int, low=1)
    assert p.check(3, "N") == [] and p.check(3.0, "N") == []     # an integral float is an integer
    assert p.convert(3.0) == 3 and type(p.convert(3.0)) is int
    for bad in (2.5, True, float("nan"), float("inf")):
        msg = p.check(bad, "N")
        assert len(msg) == 1 and "integer" in msg[0], (bad, msg)
    assert "must be >= 1" in p.check(0, "N")[0]


def test_param_float_must_be_finite():
    # energies square the parameters: anything above 1e150 would overflow (docstring of _finite)
    p = Param("f", -0.6, "h")
    assert p.check(1e150, "f") == [] and p.check(-1e150, "f") == []
    for bad in (float("nan"), float("inf"), -float("inf"), 1e151):
        msg = p.check(bad, "f")
        assert len(msg) == 1 and "finite" in msg[0], (bad, msg)
    for bad in ("abc", [1.0], True):
        msg = p.check(bad, "f")
        assert len(msg) == 1 and "a number" in msg[0], (bad, msg)
    assert type(p.convert(np.float32(0.5))) is float


def test_param_choices():
    p = Param("diagonal", "right", "h", type=str, choices=("left", "right"))
    assert p.check("left", "diagonal") == []
    msg = p.check("crossed", "diagonal")
    assert len(msg) == 1 and "left, right" in msg[0] and "'crossed'" in msg[0]


def test_param_point_length_and_finiteness():
    p = Param("probe", (0.5, 0.5), "h")
    assert p.check([0.1, 0.2], "probe") == [] and p.check(np.array([0.1, 0.2]), "probe") == []
    assert p.convert([1, 2]) == (1.0, 2.0) and all(type(c) is float for c in p.convert([1, 2]))
    for bad in ((0.1,), (0.1, 0.2, 0.3), (0.1, float("nan")), 0.5, "ab"):
        msg = p.check(bad, "probe")
        assert len(msg) == 1 and "2 finite numbers" in msg[0], (bad, msg)


def test_param_bool_and_flag():
    p = Param("with_obstacle", True, "h", flag="no-obstacle")
    assert p.option == "no-obstacle"                       # the flag replaces --with-obstacle
    assert Param("lame_mu", 1.0, "h").option == "lame-mu"  # '_' is written '-' on the command line
    assert p.check(False, "x") == [] and p.check(np.bool_(True), "x") == []
    for bad in (1, 0, "yes", 1.0):                         # no silent truthiness
        msg = p.check(bad, "x")
        assert len(msg) == 1 and "true or false" in msg[0], (bad, msg)


def test_param_none_default_is_optional():
    optional = Param("h", None, "h", type=float, low=0.0, low_strict=True)
    required = Param("f", 1.0, "h")
    assert optional.check(None, "h") == [] and optional.convert(None) is None
    assert required.check(None, "f") == ["f needs a value"]
    assert Param("mesh", None, "h", type=Path).convert("a/b.msh") == Path("a/b.msh")


def test_param_string_for_a_number_is_a_message():
    # simulate(problem, {"N": "4"}) through the Python API reaches Param.check with a str
    with pytest.raises(ProblemInputError):
        membrane.SPEC.values({"N": "4"})
    with pytest.raises(ProblemInputError):
        membrane.SPEC.values({"N": "abc"})


# ------------------------------------------------------------------------------ ProblemSpec
def _toy_spec(check=None):
    params = (Param("n_cells", 4, "cells", type=int, low=1),
              Param("stiffness", 2.0, "k", unit="N/m", low=0.0, low_strict=True),
              Param("origin", (0.0, 0.0), "o"),
              Param("with_wall", True, "w", flag="no-wall"))
    return ProblemSpec(name="toy", build=lambda comm, **v: None, params=params, check=check)


def test_values_fill_defaults_and_convert():
    spec = _toy_spec()
    assert spec.values() == {"n_cells": 4, "stiffness": 2.0, "origin": (0.0, 0.0), "with_wall": True}
    v = spec.values({"n_cells": 7.0, "origin": [1, 2]})
    assert v["n_cells"] == 7 and type(v["n_cells"]) is int
    assert v["origin"] == (1.0, 2.0) and v["stiffness"] == 2.0
    # the membrane's declared defaults are those of the paper's section 4
    m = membrane.SPEC.values()
    assert (m["N"], m["f"], m["u0"], m["g"], m["obstacle"]) == (10, -0.6, 0.02, 0.02, 0.0)


def test_values_unknown_name_lists_the_parameters():
    with pytest.raises(ProblemInputError) as e:
        _toy_spec().values({"stifness": 1.0})
    msg = one_line(e)
    assert "'stifness'" in msg and "n_cells, stiffness, origin, with_wall" in msg


def test_values_join_every_error():
    with pytest.raises(ProblemInputError) as e:
        _toy_spec().values({"n_cells": 0, "stiffness": 0.0, "origin": (1.0,)})
    parts = one_line(e).split("; ")
    assert len(parts) == 3
    assert parts[0].startswith("n_cells") and parts[1].startswith("stiffness") and parts[2].startswith("origin")


def test_values_cli_labels():
    with pytest.raises(ProblemInputError) as e:
        _toy_spec().values({"n_cells": 0, "with_wall": "no"}, cli=True)
    msg = one_line(e)
    assert msg.startswith("--n-cells must be >= 1") and "--no-wall must be true or false" in msg
    # the disc's cross-parameter check speaks the same labels
    with pytest.raises(ProblemInputError) as e:
        disc.SPEC.values({"lame_lambda": -200.0, "lame_mu": 100.0}, cli=True)
    assert "--lame-lambda + --lame-mu must be > 0" in one_line(e)


def test_values_cross_check_runs_only_on_valid_values():
    seen = []

    def check(values, label):
        seen.append(dict(values))
        return [f"{label('stiffness')} too soft"] if values["stiffness"] < 1 else []

    spec = _toy_spec(check)
    with pytest.raises(ProblemInputError) as e:
        spec.values({"stiffness": 0.5}, cli=True)
    assert one_line(e) == "--stiffness too soft"
    with pytest.raises(ProblemInputError):
        spec.values({"n_cells": -1})
    assert len(seen) == 1            # not called with a value that failed its own check


def test_membrane_probe_outside_the_square():
    with pytest.raises(ProblemInputError) as e:
        membrane.SPEC.values({"probe": (0.5, 1.5)})
    assert "probe must lie in the unit square" in one_line(e)


# ------------------------------------------------------------------------------ registry
def test_registry_get_and_names():
    assert problems.get("membrane") is membrane.SPEC and problems.get("disc") is disc.SPEC
    assert problems.names()[:2] == ["membrane", "disc"]
    assert set(problems.names(builtin=True)) >= {"membrane", "disc"}
    with pytest.raises(ProblemInputError) as e:
        problems.get("plate")
    msg = one_line(e)
    assert "'plate'" in msg and "membrane" in msg and "disc" in msg


def test_register_refuses_a_duplicate_from_another_source(clean_registry):
    with pytest.raises(TypeError):
        problems.register({"name": "x"})
    clash = ProblemSpec(name="membrane", build=membrane.SPEC.build, params=membrane.PARAMS, source="/elsewhere.py")
    with pytest.raises(ProblemInputError) as e:
        problems.register(clash)
    assert "already registered" in one_line(e) and "built in" in str(e.value)
    assert problems.get("membrane") is membrane.SPEC           # the built-in one is untouched
    # the same file may replace its own declaration (a reloaded file)
    a = ProblemSpec(name="mine", build=None, params=(), source="/a.py")
    b = ProblemSpec(name="mine", build=None, params=(), source="/a.py")
    problems.register(a)
    assert problems.register(b) is b and problems.get("mine") is b
    with pytest.raises(ProblemInputError):
        problems.register(ProblemSpec(name="mine", build=None, params=(), source="/b.py"))


# A problem file of the kind docs/add_a_problem.md describes: a stretched square with a
# Dirichlet boundary, two declared parameters.
PROBLEM_FILE = '''
"""A unit square membrane of a user's own (test problem)."""
import numpy as np
import ufl
from dolfinx import mesh as dmesh
from sdm_dolfinx.problems import Param, Problem, ProblemSpec


def build(comm, n, tension):
    msh = dmesh.create_unit_square(comm, n, n)
    return Problem(
        name="{name}", mesh=msh, shape=(),
        a=lambda u, w: tension * ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx,
        l=lambda w: -1.0 * w * ufl.dx,
        u0=lambda x: np.zeros(x.shape[1]), v0=lambda x: np.zeros(x.shape[1]),
        constraint_vertices=lambda m: np.zeros(0, dtype=np.int32),
        lower_bound=lambda x: np.zeros(x.shape[1]),
        constraint_measure=lambda q: q * ufl.dx,
        parameters={{"n": n, "tension": tension}})


PROBLEM = ProblemSpec(name="{name}", build=build,
                      params=(Param("n", 2, "cells per side", type=int, low=1),
                              Param("tension", 1.0, "tension", low=0.0, low_strict=True)))
'''


def write_file(folder, name, text):
    path = folder / name
    if COMM.rank == 0:
        path.write_text(text)
    COMM.Barrier()
    return path


def test_load_file_registers_once_with_its_source(mpi_tmp_path, clean_registry):
    path = write_file(mpi_tmp_path, "square.py", PROBLEM_FILE.format(name="user_square"))
    spec = problems.load_file(path)
    assert spec.name == "user_square" and spec.source == str(path.resolve())
    assert problems.load_file(str(path)) is spec                  # loading again: the same spec
    assert problems.names().count("user_square") == 1
    assert "user_square" not in problems.names(builtin=True)
    assert problems.resolve(str(path)) is spec and problems.get("user_square") is spec
    prob = spec.problem(COMM, n=3)
    assert prob.source == spec.source and prob.args == {"n": 3, "tension": 1.0}
    # the file's problem rebuilds from its run.json entry alone (through JSON, as on disk)
    again = problems.rebuild(json.loads(json.dumps(prob.describe())), COMM)
    assert again.args == prob.args and again.source == prob.source
    assert again.mesh.topology.index_map(2).size_global == 2 * 3 ** 2


@pytest.mark.parametrize("text, expect", [
    ("PROBLEM = (\n", "SyntaxError"),
    ("import numpy\nX = 1\n", "defines no PROBLEM"),
    ("import numpy\nraise KeyError('boom')\n", "KeyError: 'boom'"),
])
def test_load_file_errors_are_one_line(mpi_tmp_path, clean_registry, text, expect):
    path = write_file(mpi_tmp_path, "broken.py", text)
    before = problems.names()
    with pytest.raises(ProblemInputError) as e:
        problems.load_file(path)
    msg = one_line(e)
    assert expect in msg and str(path.resolve()) in msg
    assert problems.names() == before


def test_load_file_error_with_multiline_exception_is_one_line(mpi_tmp_path, clean_registry):
    path = write_file(mpi_tmp_path, "multi.py", "raise RuntimeError('boom\\nsecond line')\n")
    with pytest.raises(ProblemInputError) as e:
        problems.load_file(path)
    one_line(e)


def test_load_file_missing_or_not_python(mpi_tmp_path, clean_registry):
    with pytest.raises(ProblemInputError) as e:
        problems.load_file(mpi_tmp_path / "nowhere.py")
    assert "no such file" in one_line(e)
    path = write_file(mpi_tmp_path, "problem.txt", "PROBLEM = None\n")
    with pytest.raises(ProblemInputError) as e:
        problems.load_file(path)
    assert "not a Python file" in one_line(e)


def test_rebuild_refuses_a_problem_built_by_hand():
    # a Problem made directly (no ProblemSpec) has no args: nothing to rebuild it from
    hand = Problem(name="hand", mesh=None, shape=(), a=None, l=None, u0=lambda x: 0.0, v0=None,
                   constraint_vertices=None, lower_bound=lambda x: 0.0, constraint_measure=None)
    described = hand.describe()
    assert "args" not in described and "source" not in described
    with pytest.raises(ProblemInputError) as e:
        problems.rebuild(described)
    assert "'hand'" in one_line(e) and "no 'args'" in str(e.value)


def _round_trip(prob):
    """The run.json entry of ``prob`` written and read as JSON, rebuilt."""
    described = json.loads(json.dumps(prob.describe()))
    return described, problems.rebuild(described, COMM)


def test_membrane_args_round_trip_through_json():
    prob = membrane.problem(COMM, N=3, diagonal="left_right", probe=(0.25, 0.75), with_obstacle=False, f=-1.5)
    # every declared parameter is recorded, in JSON-compatible types
    assert set(prob.args) == {p.name for p in membrane.PARAMS}
    assert prob.args["probe"] == [0.25, 0.75] and prob.source is None
    described, again = _round_trip(prob)
    assert described["args"] == prob.args and "source" not in described
    assert again.args == prob.args and again.parameters == prob.parameters
    assert tuple(again.probe) == (0.25, 0.75)
    # the same mesh: (N+1)^2 vertices, 2 N^2 cells
    assert again.mesh.topology.index_map(0).size_global == 16
    assert again.mesh.topology.index_map(2).size_global == 18


def test_disc_args_round_trip_through_json():
    prob = disc.problem(COMM, h=12.0, radius=20.0, height=5.0, rho=2e-6, with_contact=False)
    assert set(prob.args) == {p.name for p in disc.PARAMS}
    assert prob.args["mesh_file"] is None and prob.args["h"] == 12.0
    described, again = _round_trip(prob)
    assert again.args == prob.args and again.rho == 2e-6
    # the regenerated mesh is the same mesh (same gmsh input)
    for dim in (0, 2):
        assert (again.mesh.topology.index_map(dim).size_global == prob.mesh.topology.index_map(dim).size_global)
    # the mass recorded is rho pi R^2 (a closed form)
    assert math.isclose(again.parameters["mass"], 2e-6 * math.pi * 400.0, rel_tol=1e-14)


def test_a_misspelt_default_is_refused(clean_registry):
    """A run default the package does not know (here "dT") would be ignored: refused at
    registration in one line naming it."""
    spec = ProblemSpec(name="typo", build=lambda comm: None, params=(), defaults={"dT": 0.5})
    with pytest.raises(ProblemInputError, match="unknown key.*'dT'") as e:
        problems.register(spec)
    one_line(e)


def test_default_keys_are_the_run_options():
    """The keys registration accepts are exactly the run options a problem may default (plus the
    time unit): the two lists cannot drift apart."""
    from sdm_dolfinx.run.options import TABLE
    assert set(registry.DEFAULT_KEYS) == {p.name for p in TABLE if p.problem_default} | {"time_unit"}


def test_unknown_extra_column_is_refused_in_one_line():
    """A misspelt extra column would otherwise end the run with an internal KeyError at row 0."""
    import dataclasses
    p = membrane.problem(N=2)
    with pytest.raises(ProblemInputError, match=r"unknown extra_columns 'momentum_z'; choose among contact_force"):
        dataclasses.replace(p, extra_columns=("contact_force", "momentum_z"))


@pytest.mark.parametrize("time", [5.0, np.float64(0.0)])
def test_time_that_is_not_a_constant_is_refused(time):
    """``time`` must be a scalar fem.Constant that the run sets; a bare number has no ``value``
    to set (it was accepted: np.shape(None) is () like a scalar's)."""
    import dataclasses
    p = membrane.problem(N=2)
    with pytest.raises(ProblemInputError,
                       match=r"time must be a scalar fem.Constant used by l\(w\) \(got (float|float64)\)"):
        dataclasses.replace(p, time=time)


def test_numpy_scalars_in_messages_read_as_numbers():
    """A numpy scalar given as a value is named in a refusal as the number it holds, on numpy 1
    and 2 alike (numpy 2's repr is np.float64(2.5))."""
    assert Param("n", 3, "h").complaints(np.float64(2.5)) == ["must be an integer (got 2.5)"]
    assert Param("n", 3, "h", choices=(1, 2)).complaints(np.int64(3)) == ["must be one of 1, 2 (got 3)"]
