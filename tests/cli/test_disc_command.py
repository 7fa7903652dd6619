"""The disc command: a run from the command line and a mesh of one's own (--mesh FILE.msh)."""
import json

from mpi4py import MPI

from sdm_dolfinx.cli import main as cli_main

COMM = MPI.COMM_WORLD


def test_command_line(mpi_tmp_path):
    """``python -m sdm_dolfinx disc`` writes the membrane's files with the disc's three extra
    columns and every parameter's unit in run.json; bad input exits with status 2."""
    out = mpi_tmp_path / "disc"
    assert cli_main(["disc", "--level", "1", "--dt", "1e-4", "--T", "0.001", "--out", str(out), "--quiet"]) == 0
    if COMM.rank == 0:
        header = (out / "timeseries.csv").read_text().splitlines()[0]
        assert header == ("step,t,energy,kinetic,potential,u_probe,lambda_probe,n_active,newton_its,"
                          "contact_force,momentum_x,momentum_y,elastic,gap_min_boundary")
        info = json.loads((out / "run.json").read_text())
        assert info["status"] == "finished"
        params, units = info["problem"]["parameters"], info["problem"]["units"]
        for k in ("radius", "height", "rho", "lame_lambda", "lame_mu", "gravity", "v0", "h"):
            assert k in params and k in units, k
    COMM.Barrier()
    assert cli_main(["disc", "--radius", "-1", "--out", str(mpi_tmp_path / "bad")]) == 2
