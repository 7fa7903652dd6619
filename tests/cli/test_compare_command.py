"""The compare command: bad input in one line (exit 2, nothing run or written), --list, and a tiny
grid run twice (the second run reuses every finished run: resumable)."""
import json

from mpi4py import MPI

import pytest

from sdm_dolfinx import cli
from sdm_dolfinx.compare.catalogue import CATALOGUE

COMM = MPI.COMM_WORLD
PROG = "python -m sdm_dolfinx compare: error:"

# (argv, expected fragment of the one-line message)
BAD = [
    ([], "--problem is required"),
    (["--problem", "nosuch", "--quick"], "unknown problem 'nosuch'"),
    (["--problem", "membrane", "--h", "0.1,x", "--dt", "0.01"], "not a number"),
    (["--problem", "membrane", "--h", "0", "--dt", "0.01"], "positive"),
    (["--problem", "membrane", "--h", "1/0", "--dt", "0.01"], "not a number"),
    (["--problem", "membrane", "--h", "0.1", "--dt", "-0.01"], "positive"),
    (["--problem", "membrane", "--h", "0.1", "--dt", "0.003"], "whole number of steps"),
    (["--problem", "membrane", "--h", "0.1", "--dt", "0.01", "--dt-ratio", "0.1"], "not both"),
    (["--problem", "membrane", "--h", "0.1"], "--dt"),
    (["--problem", "membrane", "--h", "0.1", "--dt", "0.01", "--methods", "sdm-p2p1,bogus"], "unknown method(s) bogus"),
    (["--problem", "membrane", "--h", "0.1", "--dt", "0.01", "--methods", ","], "--methods needs"),
    (["--problem", "membrane", "--h", "0.1", "--dt", "0.01", "--param", "f"], "NAME=VALUE"),
    (["--problem", "membrane", "--h", "0.1", "--dt", "0.01", "--param", "nosuch=1"], "no parameter 'nosuch'"),
    (["--problem", "membrane", "--h", "0.1", "--dt", "0.01", "--reference", "bogus"], "invalid choice"),
    (["--problem", "membrane", "--h", "0.1", "--dt", "0.01", "--T", "0"], "positive"),
    (["--problem", "membrane", "--quick", "--bogus"], "unrecognized"),
]


@pytest.mark.parametrize("argv, fragment", BAD)
def test_compare_refuses_bad_input_in_one_line(argv, fragment, mpi_tmp_path, capsys):
    out = mpi_tmp_path / "cmp"
    assert cli.main(["compare", *argv, "--out", str(out)]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(PROG) and fragment in err[0], err
        assert not out.exists()


def test_compare_lists_every_method(capsys):
    assert cli.main(["compare", "--list"]) == 0
    if COMM.rank == 0:
        lines = capsys.readouterr().out.strip().splitlines()
        assert [ln.split()[0] for ln in lines] == [m.name for m in CATALOGUE]


def test_compare_is_resumable_and_reports_refusals(mpi_tmp_path, capsys):
    """Two methods on the rod at one (h, dt) against its closed form: a method the problem refuses (the
    constraint at every boundary node: in 1-D the contact boundary is one vertex) is reported as
    refused, not a crash; a rerun computes nothing and writes the same table."""
    out = mpi_tmp_path / "cmp"
    argv = ["compare", "--problem", "rod1d", "--methods", "sdm-p2p1,sdm-nodes", "--h", "1/10", "--dt", "0.05",
            "--T", "0.5", "--out", str(out)]
    assert cli.main(argv) == 0
    first = capsys.readouterr().out
    table = (out / "compare.csv").read_text() if COMM.rank == 0 else None
    assert cli.main(argv) == 0
    second = capsys.readouterr().out
    if COMM.rank == 0:
        data = json.loads((out / "compare.json").read_text())
        status = {r["method"]: r["status"] for r in data["records"]}
        assert status == {"sdm-p2p1": "finished", "sdm-nodes": "refused"}
        assert "done before" not in first and "[1/2]" in first
        assert "2 of 2 runs done before" in second and "[1/2]" not in second
        for name in ("compare.csv", "ranking.md", "ranking.html", "compare_convergence.png", "compare_energy.png"):
            assert (out / name).exists(), name
        assert (out / "compare.csv").read_text() == table and table.count("\n") == 3     # header + two runs
        assert "refused: in 1-D" in (out / "ranking.md").read_text()


def _run_T(out):
    """T of every run.json under ``out`` (rank 0)."""
    return sorted({json.loads(p.read_text())["T"] for p in out.rglob("run.json")})


@pytest.mark.parametrize("first, second, changed", [
    (["--problem", "rod1d", "--T", "0.5"], ["--problem", "rod1d", "--T", "1.5"], "T"),
    (["--problem", "bar", "--T", "1.0", "--param", "v=2"], ["--problem", "bar", "--T", "1.0", "--param", "v=1"],
     "params"),
])
def test_compare_never_reuses_a_run_of_other_settings(first, second, changed, mpi_tmp_path, capsys):
    """The same --out with another T (or another problem parameter) runs every method again: compare.json
    and the runs' run.json agree on what was run (a stored run is reused only when everything that defines
    it matches: problem, parameters, h, dt, T, method options, reference, package version)."""
    out = mpi_tmp_path / "cmp"
    grid = ["--methods", "sdm-p2p1,penalty-midpoint", "--h", "0.1", "--dt", "0.01", "--out", str(out)]
    assert cli.main(["compare", *first, *grid]) == 0
    capsys.readouterr()
    assert cli.main(["compare", *second, *grid]) == 0
    said = capsys.readouterr().out
    if COMM.rank == 0:
        assert "done before" not in said and said.count("ran again") == 2 and changed in said
        data = json.loads((out / "compare.json").read_text())
        T = float(second[second.index("--T") + 1])
        assert _run_T(out) == [T] and all(r["T"] == T for r in data["records"])
        if changed == "params":
            args = {json.loads(p.read_text())["problem"]["args"]["v"] for p in out.rglob("run.json")}
            assert args == {1.0} and all(r["params"]["v"] == 1.0 for r in data["records"])
    assert cli.main(["compare", *second, *grid]) == 0                    # now the same runs: reused
    if COMM.rank == 0:
        assert "2 of 2 runs done before" in capsys.readouterr().out


def test_a_window_without_contact_ranks_no_contact_metric(mpi_tmp_path):
    """compare on the rod up to T = 0.5 (first impact at t = 1): the contact-phase metrics are not defined
    (not 0 for everybody), nobody is ranked on them, and ranking.md says the window has no contact."""
    out = mpi_tmp_path / "cmp"
    assert cli.main(["compare", "--problem", "rod1d", "--methods", "sdm-p2p1,penalty-midpoint,standard-newmark",
                     "--h", "0.1", "--dt", "0.01", "--T", "0.5", "--out", str(out)]) == 0
    if COMM.rank == 0:
        data = json.loads((out / "compare.json").read_text())
        for m in data["ranking"]["methods"].values():
            assert not {"stress_contact_L2t", "oscillation_index", "release_time_error"} & set(m["ranks"])
            assert m["values"]["stress_contact_L2t"] != 0.0
        text = (out / "ranking.md").read_text()
        assert "This comparison has no contact in [0, 0.5]" in text and "| n/d |" in text


def test_compare_takes_a_problem_file(mpi_tmp_path):
    """compare --problem-file: the docs' my_block.py (its mesh size the parameter n, no exact solution)
    is compared against the refined reference run, as the built-in problems without one are; a changed
    file runs again (its SHA-256 is part of what defines a run)."""
    import re
    from pathlib import Path
    doc = (Path(__file__).resolve().parents[2] / "docs" / "add_a_problem.md").read_text()
    f = mpi_tmp_path / "my_block.py"
    if COMM.rank == 0:
        f.write_text(re.search(r"Save as `my_block.py`.*?```python\n(.*?)```", doc, re.S).group(1))
    COMM.Barrier()
    out = mpi_tmp_path / "cmp"
    argv = ["compare", "--problem-file", str(f), "--methods", "sdm-p2p1,penalty-midpoint", "--h", "10",
            "--dt", "4e-5", "--T", "8e-4", "--out", str(out)]
    from sdm_dolfinx.problems import registry
    saved = dict(registry._REGISTRY)
    try:
        assert cli.main(argv) == 0
        if COMM.rank == 0:
            data = json.loads((out / "compare.json").read_text())
            assert data["problem"] == "my_block" and "reference run" in (out / "ranking.md").read_text()
            assert {r["params"]["n"] for r in data["records"]} == {2}
            f.write_text(f.read_text().replace('Param("E", 1000.0', 'Param("E", 2000.0'))
        COMM.Barrier()
        registry._REGISTRY.clear()
        registry._REGISTRY.update(saved)
        assert cli.main(argv) == 0
        if COMM.rank == 0:
            recs = json.loads((out / "compare.json").read_text())["records"]
            assert all("problem_file_sha256" in r.get("ran_again_because", []) for r in recs)
    finally:
        registry._REGISTRY.clear()
        registry._REGISTRY.update(saved)
    assert cli.main(["compare", "--problem", "rod1d", "--problem-file", str(f), "--quick"]) == 2
