"""The energy command refuses bad input in one line."""
from mpi4py import MPI

from sdm_dolfinx import cli

COMM = MPI.COMM_WORLD


def test_energy_command_refuses_bad_input(mpi_tmp_path, capsys):
    assert cli.main(["energy"]) == 2
    assert cli.main(["energy", str(mpi_tmp_path / "nothing")]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err.strip().splitlines()
        assert err and all(line.startswith("python -m sdm_dolfinx energy: error:") for line in err)

