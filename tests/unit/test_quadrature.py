"""The quadrature degree of the discretisation's forms (``--quadrature-degree``,
:mod:`sdm_dolfinx.method.quadrature`).

On the disc's curved P2 cells the stiffness integrand is rational: the default degree there
must give entries that a higher degree no longer changes (checked on the paper's coarsest
mesh, GetFEM's ``disc_P2_h4.mesh``, when it is here, and always on our level 1 disc, which has
as many curved cells), while UFL's estimate does not. On the affine membrane UFL's estimate is
exact: a high degree changes nothing but round-off. The degree used is in ``run.json``, a
``run.json`` without it (older runs) is rebuilt with UFL's estimates, and bad values are
refused in one line.
"""
import json
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
import ufl

from sdm_dolfinx import cli, compat, post, simulate
from sdm_dolfinx.method import quadrature
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.run.integrator import Integrator
from sdm_dolfinx.method.pairs import PAIRS
from sdm_dolfinx.problems import disc, membrane
from sdm_dolfinx.run import plan
from sdm_dolfinx.paper.design import PAPER_MESH_DIRS, paper_mesh_dir

COMM = MPI.COMM_WORLD
#: where sdm_dolfinx looks for them ($SDM_GETFEM_MESHES, then shared/ beside the checkout or a parent folder)
DATA = paper_mesh_dir() or PAPER_MESH_DIRS[1]
COARSEST = DATA / "disc_P2_h4.mesh"
#: "no change": relative to the matrix's largest entry, well above round-off (~5e-15 measured)
#: and far below the error of UFL's estimate on curved cells (2e-6 to 7e-6 measured)
CONVERGED = 1e-11
#: UFL's estimate exact: the same entries up to the summation order of two quadrature rules
EXACT = 1e-14


def _max_entry(X):
    """max |X_ij| over every rank (a PETSc Mat or Vec)."""
    data = X.getValuesCSR()[2] if hasattr(X, "getValuesCSR") else X.array_r
    return COMM.allreduce(float(np.max(np.abs(data), initial=0.0)), op=MPI.MAX)


def _change(X, Y):
    """max |Y - X| / max |X| (entries)."""
    D = Y.copy()
    D.axpy(-1.0, X)
    out = _max_entry(D) / _max_entry(X)
    D.destroy()
    return out


def _matrices(d):
    """The discretisation's assembled forms: A, L, B and C (or the standard M), the lumped measure."""
    out = {"A": d.A, "L": d.L}
    out.update({k: getattr(d, k) for k in ("B", "C") if getattr(d, k) is not None})
    if d.B is None:
        out["M"] = d.M
    return out


def _curved_disc(which):
    """The disc on the paper's coarsest mesh (skipped, with the reason, when the file or its
    reader is missing) or on our level 1 mesh (always there)."""
    if which == "level 1":
        return disc.problem(COMM, level=1)
    if not COMM.bcast(COARSEST.is_file() if COMM.rank == 0 else None, root=0):
        pytest.skip(f"the paper's coarsest disc mesh is not in {DATA} (the level 1 disc is checked instead)")
    try:
        return disc.problem(COMM, mesh_file=COARSEST)
    except Exception as e:        # no reader of GetFEM's format yet: the level 1 case still runs
        pytest.skip(f"cannot read {COARSEST.name} ({type(e).__name__}: {e}); the level 1 disc is checked instead")


@pytest.mark.mpi
@pytest.mark.parametrize("which", ["GetFEM disc_P2_h4", "level 1"])
@pytest.mark.parametrize("pair", list(PAIRS))
def test_curved_default_is_converged(which, pair):
    """On curved P2 cells the default degree is converged: 2 more change no entry of A, L, B,
    C (M) by more than CONVERGED relative; UFL's estimate leaves A wrong by far more."""
    problem = _curved_disc(which)
    d = Discretisation(problem, pair)
    assert d.quadrature_degree == quadrature.CURVED_DEGREE
    finer = Discretisation(problem, pair, quadrature_degree=d.quadrature_degree + 2)
    other = _matrices(finer)
    changes = {k: _change(m, other[k]) for k, m in _matrices(d).items()}
    assert max(changes.values()) <= CONVERGED, changes
    measure = COMM.allreduce(float(np.max(np.abs(finer.cmeasure - d.cmeasure), initial=0.0)), op=MPI.MAX)
    assert measure <= CONVERGED * COMM.allreduce(float(np.max(d.cmeasure, initial=0.0)), op=MPI.MAX)
    estimated = Discretisation(problem, pair, quadrature_degree=quadrature.ESTIMATED)
    assert _change(d.A, estimated.A) > 1e-8         # the error the default removes (2e-6 to 7e-6 measured)


def test_block_system_uses_the_degree():
    """The consistent-mass (U, V) block matrix of the integrator is assembled at the
    discretisation's degree too (converged on curved cells, not UFL's estimate)."""
    problem = disc.problem(COMM, level=1)
    K = {}
    for q in (None, quadrature.CURVED_DEGREE + 2, quadrature.ESTIMATED):
        d = Discretisation(problem, "P2/P1", "consistent", quadrature_degree=q)
        K[q] = Integrator(d, "midpoint", 1e-4).K_full
    assert _change(K[None], K[quadrature.CURVED_DEGREE + 2]) <= CONVERGED
    assert _change(K[None], K[quadrature.ESTIMATED]) > 1e-8


@pytest.mark.parametrize("pair", list(PAIRS))
def test_affine_default_is_exact(pair):
    """Affine membrane: the default is UFL's estimate, already exact (a high degree changes only
    round-off)."""
    problem = membrane.problem(COMM, N=4)
    d = Discretisation(problem, pair)
    assert d.quadrature_degree == quadrature.ESTIMATED
    high = _matrices(Discretisation(problem, pair, quadrature_degree=quadrature.CURVED_DEGREE + 2))
    changes = {k: _change(m, high[k]) for k, m in _matrices(d).items()}
    assert max(changes.values()) <= EXACT, changes


def test_form_keyword_sets_the_degree():
    """compat.form(..., quadrature_degree=q) changes the rule ffcx compiles (q = 1 gives another
    matrix than the estimate), except for an integral whose measure names its own degree."""
    problem = disc.problem(COMM, level=1)
    W = compat.function_space(problem.mesh, compat.element("Lagrange", "triangle", 2, (2,)))
    u, w = ufl.TrialFunction(W), ufl.TestFunction(W)
    a = problem.a(u, w)
    A0 = compat.assemble_matrix(compat.form(a))
    assert _change(A0, compat.assemble_matrix(compat.form(a, quadrature_degree=1))) > 0.1
    own = ufl.inner(ufl.grad(u), ufl.grad(w)) * ufl.dx(metadata={"quadrature_degree": 2})
    assert _change(compat.assemble_matrix(compat.form(own)),
                   compat.assemble_matrix(compat.form(own, quadrature_degree=12))) == 0.0


def _run_json(folder):
    return COMM.bcast(json.loads((Path(folder) / "run.json").read_text()) if COMM.rank == 0 else None, root=0)


@pytest.mark.parametrize("problem,params,option,recorded", [
    ("disc", {"level": 1}, None, quadrature.CURVED_DEGREE),
    ("disc", {"level": 1}, 14, 14),
    ("disc", {"level": 1}, quadrature.ESTIMATED, quadrature.ESTIMATED),
    ("membrane", {"N": 3}, None, quadrature.ESTIMATED),
])
def test_run_json_records_the_degree(problem, params, option, recorded, mpi_tmp_path):
    """run.json: the option as given (run_options) and the degree used (quadrature_degree)."""
    out = mpi_tmp_path / "run"
    dt = 1e-4 if problem == "disc" else 1e-2
    simulate(problem, params, out=out, dt=dt, T=3 * dt, quadrature_degree=option)
    info = _run_json(out)
    assert info["run_options"]["quadrature_degree"] == option
    assert info["quadrature_degree"] == recorded


def _strip_degree(folder, status=None, recorded=None):
    """run.json as an older version wrote it (no degree), or with another recorded degree."""
    if COMM.rank == 0:
        path = Path(folder) / "run.json"
        info = json.loads(path.read_text())
        info["run_options"].pop("quadrature_degree", None)
        info.pop("quadrature_degree", None)
        if recorded is not None:
            info["quadrature_degree"] = recorded
        if status is not None:
            info["status"] = status
        path.write_text(json.dumps(info))
    COMM.Barrier()


@pytest.mark.mpi
@pytest.mark.filterwarnings("ignore::sdm_dolfinx.run.result.BoundaryGapWarning")
def test_old_run_is_rebuilt_with_estimated_degrees(mpi_tmp_path):
    """A disc run made with UFL's estimates whose run.json predates the option: the energy
    recomputed from its fields matches its own to round-off (so the rebuild used the
    estimates), but not when run.json claims the default degree; a restart keeps the estimates."""
    out = mpi_tmp_path / "old"
    simulate("disc", {"level": 1}, out=out, pair="P2/P1", dt=1e-4, T=0.015, write_every=5,
           quadrature_degree=quadrature.ESTIMATED)            # the contact starts near t = 0.01
    _strip_degree(out)
    res = post.recompute_energy(out, COMM, write=False)
    assert res["max_roundoff_ratio"] <= 300 * np.finfo(np.dtype(res["stored_dtype"])).eps
    _strip_degree(out, recorded=quadrature.CURVED_DEGREE)
    wrong = post.recompute_energy(out, COMM, write=False)
    assert wrong["max_rel_diff"] > 1e3 * max(res["max_rel_diff"], 1e-16)
    _strip_degree(out, status="interrupted")
    assert plan(out=out, restart=True).options["quadrature_degree"] == quadrature.ESTIMATED


@pytest.mark.parametrize("argv,toml,message", [
    (["--quadrature-degree", "-1"], None, "--quadrature-degree: -1 is out of range: from 1 to 30"),
    (["--quadrature-degree", "abc"], None, "--quadrature-degree: 'abc' is not an integer"),
    (["--quadrature-degree", "100"], None, "--quadrature-degree: 100 is out of range"),
    (["--quadrature-degree", "0"], None, "out of range"),
    ([], "quadrature-degree = 100\n", "key 'quadrature-degree': 100 is out of range"),
    ([], "quadrature-degree = 2.5\n", "key 'quadrature-degree': expected an integer, 'auto' or 'estimated'"),
    ([], 'quadrature-degree = "exact"\n', "key 'quadrature-degree': 'exact' is not an integer"),
])
def test_bad_degree_is_refused(argv, toml, message, mpi_tmp_path, capsys):
    """One line, exit status 2, nothing written."""
    out = mpi_tmp_path / "never"
    argv = ["membrane", "--out", str(out)] + argv
    if toml is not None:
        if COMM.rank == 0:
            (mpi_tmp_path / "bad.toml").write_text(toml)
        COMM.Barrier()
        argv += ["--config", str(mpi_tmp_path / "bad.toml")]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert not out.exists()


def test_api_refuses_a_bad_degree():
    """The Python API says the same in one line (RunInputError before anything is built)."""
    with pytest.raises(ValueError, match="quadrature_degree must be an integer from 1 to 30"):
        plan("membrane", {"N": 2}, quadrature_degree=31)
    with pytest.raises(ValueError, match="quadrature_degree"):
        Discretisation(membrane.problem(COMM, N=2), "P1+/P0", quadrature_degree=True)


def test_toml_and_command_line_degree_reach_the_run(mpi_tmp_path):
    """``quadrature-degree = 14`` in TOML and ``--quadrature-degree estimated`` on the command
    line are run options like the others."""
    toml = mpi_tmp_path / "run.toml"
    if COMM.rank == 0:
        toml.write_text("quadrature-degree = 14\nlevel = 1\ndt = 1e-4\nT = 2e-4\n")
    COMM.Barrier()
    for extra, recorded in (([], 14), (["--quadrature-degree", "estimated"], quadrature.ESTIMATED)):
        out = mpi_tmp_path / f"run{recorded}"
        assert cli.main(["disc", "--config", str(toml), "--out", str(out), "--quiet"] + extra) == 0
        assert _run_json(out)["quadrature_degree"] == recorded
