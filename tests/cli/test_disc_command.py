"""The disc command: a run from the command line and a mesh of one's own (--mesh FILE.msh)."""
import json

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import disc, simulate
from sdm_dolfinx.problems import disc_mesh
from sdm_dolfinx.cli import main as cli_main

COMM = MPI.COMM_WORLD


R, HEIGHT, V0, G = 20.0, 10.0, -1000.0, 9810.0       # the defaults (mm, mm, mm/s, mm/s^2)


_RUNS = {}


def run(pair="P2/P1", dt=1e-4, T=0.02, scheme="midpoint", **problem_args):
    """A level-1 run, cached: only the time series and scalars are kept (no PETSc objects)."""
    key = (pair, dt, T, scheme, tuple(sorted(problem_args.items())))
    if key not in _RUNS:
        r = simulate(disc.problem(level=1, **problem_args), pair=pair, scheme=scheme, dt=dt, T=T)
        _RUNS[key] = {"ts": r.timeseries, "info": r.info, "gap_imposed": r.gap_imposed.copy()}
    return _RUNS[key]


def test_command_line(mpi_tmp_path):
    """``python -m sdm_dolfinx disc`` writes the membrane's files with the disc's three extra
    columns and every parameter's unit in run.json; bad input exits with status 2."""
    out = mpi_tmp_path / "disc"
    assert cli_main(["disc", "--level", "1", "--dt", "1e-4", "--T", "0.001", "--out", str(out), "--quiet"]) == 0
    if COMM.rank == 0:
        header = (out / "timeseries.csv").read_text().splitlines()[0]
        assert header == ("step,t,energy,kinetic,potential,u_probe,lambda_probe,n_active,newton_its,"
                          "contact_force,momentum_y,elastic")
        info = json.loads((out / "run.json").read_text())
        assert info["status"] == "finished"
        params, units = info["problem"]["parameters"], info["problem"]["units"]
        for k in ("radius", "height", "rho", "lame_lambda", "lame_mu", "gravity", "v0", "h"):
            assert k in params and k in units, k
    COMM.Barrier()
    assert cli_main(["disc", "--radius", "-1", "--out", str(mpi_tmp_path / "bad")]) == 2


def test_mesh_file_gives_the_same_run(mpi_tmp_path, capsys):
    """``disc --mesh FILE.msh``: the level-1 mesh written to a file and read back gives the
    run of the generated mesh (same nodes, written with 16 digits: 1e-9 relative, through
    the impact); a missing, unreadable or mismatched file is bad input (status 2, one line)."""
    path = mpi_tmp_path / "disc.msh"
    if COMM.rank == 0:
        disc_mesh.write_msh(path, disc_mesh.LEVELS[1], radius=R, centre=(0.0, R + HEIGHT))
    COMM.Barrier()
    kw = dict(pair="P2/P1", dt=1e-4, T=0.012)
    a = simulate(disc.problem(mesh_file=path), **kw)
    b = run(**kw)
    assert a.info["problem"]["parameters"]["mesh_file"] == str(path)
    assert a.info["dim_W"] == b["info"]["dim_W"] and b["ts"]["n_active"].max() > 0
    np.testing.assert_array_equal(a.timeseries["n_active"], b["ts"]["n_active"])
    for c in ("energy", "u_probe", "lambda_probe", "contact_force", "momentum_y"):
        scale = np.max(np.abs(b["ts"][c]))
        np.testing.assert_allclose(a.timeseries[c], b["ts"][c], rtol=0, atol=1e-9 * scale, err_msg=c)
    junk = mpi_tmp_path / "junk.msh"
    if COMM.rank == 0:
        junk.write_text("$MeshFormat\nnot a mesh\n")
    COMM.Barrier()
    out = mpi_tmp_path / "never"
    for args, message in ((["--mesh", str(mpi_tmp_path / "missing.msh")], "no such file"),
                          (["--mesh", str(junk)], "junk.msh"),
                          (["--mesh", str(path), "--radius", "25"], "not the disc of radius 25"),
                          (["--mesh", str(path), "--h", "3"], "choose one")):
        assert cli_main(["disc", *args, "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        if COMM.rank == 0:
            assert message in err and len(err.strip().splitlines()) == 1, err
        assert not out.exists()

