"""The energy command refuses bad input in one line, before computing anything."""

from mpi4py import MPI

import pytest

from sdm_dolfinx import cli
from sdm_dolfinx.cli import energy as energy_command

COMM = MPI.COMM_WORLD


def test_energy_command_refuses_bad_input(mpi_tmp_path, capsys):
    assert cli.main(["energy"]) == 2
    assert cli.main(["energy", str(mpi_tmp_path / "nothing")]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err.strip().splitlines()
        assert err and all(line.startswith("python -m sdm_dolfinx energy: error:") for line in err)



def _run(folder):
    """A finished two-step membrane run in ``folder``."""
    assert cli.main(["membrane", "--N", "4", "--dt", "0.01", "--T", "0.02", "--quiet", "--out", str(folder)]) == 0
    COMM.Barrier()


@pytest.mark.parametrize("damage, message", [
    ("no step", "timeseries.csv has no column 'step'"),
    ("no energy", "timeseries.csv has no column 'energy'"),
    ("read-only", "cannot write"),
    ("csv is a folder", "energy_recomputed.csv is a folder"),
])
def test_energy_checks_before_computing(damage, message, mpi_tmp_path, capsys, monkeypatch, read_only):
    """A time series without the columns the comparison needs, or a folder the result cannot
    be written to, is refused at once (nothing computed, nothing written)."""
    folder = mpi_tmp_path / "run"
    _run(folder)
    csv = folder / "timeseries.csv"
    if COMM.rank == 0:
        if damage.startswith("no "):
            column = damage[3:]
            lines = [line.split(",") for line in csv.read_text().splitlines()]
            keep = [i for i, c in enumerate(lines[0]) if c != column]
            csv.write_text("\n".join(",".join(r[i] for i in keep) for r in lines) + "\n")
        elif damage == "csv is a folder":
            (folder / "energy_recomputed.csv").mkdir()
    COMM.Barrier()

    def never(*args, **kwargs):
        raise AssertionError("the energies were computed")
    monkeypatch.setattr(energy_command, "recompute_energy", never)
    if damage == "read-only":
        read_only(folder, True)
    try:
        assert cli.main(["energy", str(folder)]) == 2
    finally:
        if damage == "read-only":
            read_only(folder, False)
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert err.startswith("python -m sdm_dolfinx energy: error:") and err.count("\n") == 1, err
        assert message in err, err
    assert not (folder / "energy_recomputed.csv").is_file()
