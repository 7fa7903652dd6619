"""``python -m sdm_dolfinx inspect --constrain nodes`` (and ``weighted``): condition (7) with the constraint
at every dof of W^h on the constrained boundary (the weighted gap's rows), reported with its number;
one-line refusals."""
import json

from mpi4py import MPI

import pytest

from sdm_dolfinx import cli
from sdm_dolfinx.analysis import TOL

COMM = MPI.COMM_WORLD


def test_block_p2_p1_with_nodes_is_measured_and_reported(mpi_tmp_path, capsys):
    out = mpi_tmp_path / "nodes.json"
    rc = cli.main(["inspect", "--problem", "block", "--pair", "all", "--constrain", "nodes", "--nx", "6", "--ny", "3",
                   "--json", str(out)])
    assert rc == 0
    COMM.Barrier()
    doc = json.loads(out.read_text())
    assert doc["constrain"] == "nodes" and doc["skipped"] == ["P1+/P0", "P1/P0", "P1/P1", "P1+/P1"]
    rows = {r["pair"]: r for r in doc["results"]}
    assert set(rows) == {"P2/P1", "P2/P2"}
    p2p1 = rows["P2/P1"]
    # the 2 nx + 1 = 13 bottom nodes; the verdict is the measurement's, whatever it is
    assert p2p1["N_g"] == 13 and p2p1["constrain"] == "nodes"
    assert p2p1["verdict"] == ("well-posed" if p2p1["beta"] > TOL else "ill-posed")
    assert rows["P2/P2"]["verdict"] == "ill-posed"                 # standard Galerkin: Ker(B) = {0}
    if COMM.rank == 0:
        text = capsys.readouterr().out
        assert "skipped P1+/P0, P1/P0, P1/P1, P1+/P1" in text
        assert "every dof of W^h on the constrained boundary" in text and f"= {p2p1['beta']:.6g}" in text


def test_the_weighted_gap_is_measured_and_reported(capsys):
    """The command docs/contact.md gives (it ended in an internal error: the report had no words for the
    weighted rows): every pair measured, P2/P1 well-posed, the report naming the weighted rows."""
    assert cli.main(["inspect", "--problem", "block", "--pair", "all", "--constrain", "weighted", "--nx", "6",
                     "--ny", "3"]) == 0
    if COMM.rank == 0:
        text = capsys.readouterr().out
        assert text.count("the weighted gap's rows") == 6 and "pair P2/P1" in text and "WELL-POSED" in text


@pytest.mark.parametrize("argv, message", [
    (["--problem", "block", "--pair", "P1/P1", "--constrain", "nodes"],
     "--constrain nodes is --constrain vertices for pair P1/P1"),
    (["--problem", "block", "--pair", "P2/P1", "--constrain", "nodes", "--coulomb-bound"], "drop --constrain nodes"),
    (["--problem", "block", "--pair", "P2/P1", "--constrain", "weighted", "--coulomb-bound"],
     "drop --constrain weighted"),
    (["--problem", "block", "--constrain", "edges"], "invalid choice: 'edges'"),
])
def test_bad_input_one_line_exit_2(argv, message, capsys):
    assert cli.main(["inspect", *argv]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("python -m sdm_dolfinx inspect: error:")
        assert message in err and "Traceback" not in err
