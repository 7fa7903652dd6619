"""A problem file whose data cannot make a run is refused before the run, in one line naming the
file (exit 2, nothing written): a build without return, a lower_bound of the wrong shape,
constraint vertices out of range, NaN in u0 or v0, zero-area cells, rho <= 0, and a parameter
named like a run option or an option of the command line (its --option would clash)."""
import re
from pathlib import Path

from mpi4py import MPI

import pytest

from sdm_dolfinx import cli, simulate
from sdm_dolfinx.errors import SdmError

COMM = MPI.COMM_WORLD
DOC = Path(__file__).resolve().parents[2] / "docs" / "add_a_problem.md"
SMALL = ["--n", "4", "--T", "4e-4", "--quiet"]

#: (name, text of the docs' my_block.py, its replacement, what the one line says besides the file)
BROKEN = [
    ("noreturn", "    return Problem(", "    Problem(", "build(comm, ...) returned None, not a Problem"),
    ("bound_shape", "lower_bound=lambda x: -x[1],", "lower_bound=lambda x: -x[:2],",
     "lower_bound returned an array of shape (2, "),
    ("bound_nan", "lower_bound=lambda x: -x[1],", "lower_bound=lambda x: -x[1] / 0.0 * 0.0,",
     "lower_bound returned non-finite values"),
    ("vertices", "constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom),",
     "constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom) + 10**6,",
     "constraint_vertices returned vertex indices outside"),
    ("vertices_negative", "constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom),",
     "constraint_vertices=lambda m: dmesh.locate_entities_boundary(m, 0, bottom) - 10**6,",
     "constraint_vertices returned vertex indices outside"),
    ("u0_nan", "u0=lambda x: np.zeros((2, x.shape[1])),", "u0=lambda x: np.full((2, x.shape[1]), np.nan),",
     "u0 gives non-finite values"),
    ("v0_inf", "v0=lambda x: np.vstack([np.zeros(x.shape[1]), np.full(x.shape[1], v0)]),",
     "v0=lambda x: np.vstack([np.zeros(x.shape[1]), np.full(x.shape[1], np.inf)]),", "v0 gives non-finite values"),
    ("zero_area", "    fdim = msh.topology.dim - 1", "    msh.geometry.x[:, 1] = gap\n    fdim = msh.topology.dim - 1",
     "cells have zero measure"),
    ("rho_negative", 'shape=(2,), rho=rho,', 'shape=(2,), rho=-rho,', "rho must be a finite number > 0"),
    ("rho_zero", 'shape=(2,), rho=rho,', 'shape=(2,), rho=0.0,', "rho must be a finite number > 0"),
]
#: a parameter named like an option of every run, of a method, or of the command line
CLASHES = [("mu", "the run option --mu"), ("dt", "the run option --dt"), ("out", "the command line's --out"),
           ("penalty", "the run option --penalty"), ("problem_file", "the command line's --problem-file"),
           ("json", "the command line's --json")]


#: each test's problem file (another folder each time) registers afresh: the registry is restored after
pytestmark = pytest.mark.usefixtures("clean_registry")


def block_text():
    return re.search(r"Save as `my_block.py`.*?```python\n(.*?)```", DOC.read_text(), re.S).group(1)


def write(folder, name, text):
    path = folder / f"{name}.py"
    if COMM.rank == 0:
        path.write_text(text)
    COMM.Barrier()
    return path


def broken_file(folder, name, old, new):
    text = block_text()
    assert text.count(old) == 1, old
    return write(folder, name, text.replace(old, new))


def clash_file(folder, name):
    text = block_text()
    old = 'Param("n", 10, "cells along the width", type=int, low=1)),'
    assert old in text
    text = text.replace(old, old[:-2] + f', Param("{name}", 0.1, "a parameter named like an option")),')
    text = text.replace("def build(comm, width, height, gap, E, nu, rho, v0, n):",
                        f"def build(comm, width, height, gap, E, nu, rho, v0, n, {name}):")
    return write(folder, f"clash_{name}", text)


def refused(argv, message, path, out, capsys):
    capsys.readouterr()
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err and "internal error" not in err, err
        assert message in err and str(path.resolve()) in err, err
    assert not out.exists()


@pytest.mark.parametrize("name,old,new,message", BROKEN)
def test_broken_problem_file_is_refused(name, old, new, message, mpi_tmp_path, capsys):
    path = broken_file(mpi_tmp_path, name, old, new)
    out = mpi_tmp_path / "never"
    refused(["run", "--problem-file", str(path), *SMALL, "--out", str(out)], message, path, out, capsys)
    with pytest.raises(SdmError) as e:              # the API: the same line, an SdmError
        simulate(str(path), {"n": 4}, T=4e-4, out=out)
    assert message in str(e.value) and str(path.resolve()) in str(e.value) and "\n" not in str(e.value)
    assert not out.exists()


@pytest.mark.parametrize("name,message", CLASHES)
def test_parameter_named_like_an_option_is_refused(name, message, mpi_tmp_path, capsys):
    path = clash_file(mpi_tmp_path, name)
    out = mpi_tmp_path / "never"
    option = name.replace("_", "-")
    expected = f"parameter {name!r} (--{option}) is named like {message}"
    refused(["run", "--problem-file", str(path), *SMALL, "--out", str(out)], expected, path, out, capsys)
    refused(["inspect", "--problem-file", str(path), "--n", "2"], expected, path, out, capsys)
    with pytest.raises(SdmError) as e:
        simulate(str(path), {"n": 4}, T=4e-4, out=out)
    assert expected in str(e.value) and "\n" not in str(e.value)


def test_reserved_names_cover_the_command_line():
    """Every option of the run commands and of inspect is a reserved name (the list the clash
    check uses, docs/add_a_problem.md's), and the page lists every reserved name."""
    from sdm_dolfinx.cli import inspect as cli_inspect, run as cli_run
    from sdm_dolfinx.problems import get
    from sdm_dolfinx.run import options as run_options
    reserved = run_options.reserved_names()
    parsers = [cli_run.build_parser(None, "run"), cli_run.build_parser(get("membrane"), "membrane"),
               cli_inspect.build_parser(get("membrane"))]
    params = {p.option for p in get("membrane").params}
    for parser in parsers:
        for action in parser._actions:
            for opt in action.option_strings:
                if opt.startswith("--") and opt[2:] not in params:
                    assert opt[2:].replace("-", "_") in reserved, opt
    page = DOC.read_text()
    assert all(f"`{n}`" in page for n in run_options.COMMAND_LINE_NAMES)
