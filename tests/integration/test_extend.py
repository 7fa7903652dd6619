"""A finished run extended to a later T: ``--restart DIR --T LATER`` (``simulate(out=DIR,
restart=True, T=LATER)``) continues it from the checkpoint every run writes at its end; the
extended run is the uninterrupted run to the later T (bit for bit on 1 rank); run.json records
the extension; a T that is not later, or not a whole number of steps, is refused in one line
and nothing is changed."""
import json

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli, membrane, simulate
from sdm_dolfinx.run import Interrupted, RunInputError

COMM = MPI.COMM_WORLD
#: 1 rank: bit for bit; 2 ranks: the restarted process factorises anew (docs/outputs.md: round-off)
RTOL = 0.0 if COMM.size == 1 else 1e-9
#: the membrane touches its obstacle after t = 0.2: the extension runs through the impact
ARGS = ["membrane", "--N", "8", "--dt", "2e-3", "--write-every", "5", "--quiet"]


def text(path):
    return COMM.bcast(path.read_text() if COMM.rank == 0 else None, root=0)


def info(folder):
    return json.loads(text(folder / "run.json"))


def rows(folder):
    return np.loadtxt(text(folder / "timeseries.csv").splitlines(), delimiter=",", skiprows=1, ndmin=2)


def last_state(folder):
    import h5py
    if COMM.rank != 0:
        return None
    with h5py.File(folder / "state.h5", "r") as h5:
        return int(h5["step"][-1]), h5["U"][-1], h5["V"][-1]


def same_run(ref, ext):
    """ext's time series and final state are ref's (bit for bit on 1 rank)."""
    a, b = rows(ref), rows(ext)
    assert a.shape == b.shape
    if RTOL == 0.0:
        assert text(ref / "timeseries.csv") == text(ext / "timeseries.csv")
    else:
        assert np.allclose(a, b, rtol=RTOL, atol=RTOL * np.abs(a).max(axis=0))
    if COMM.rank == 0:
        (sa, ua, va), (sb, ub, vb) = last_state(ref), last_state(ext)
        assert sa == sb == a.shape[0] - 1
        assert np.allclose(ua, ub, rtol=0, atol=RTOL * np.abs(ua).max())
        assert RTOL > 0 or np.array_equal(va, vb)


def test_cli_extends_a_finished_run(mpi_tmp_path, capsys):
    ref, ext = mpi_tmp_path / "ref", mpi_tmp_path / "ext"
    assert cli.main(ARGS + ["--T", "0.4", "--out", str(ref)]) == 0
    assert cli.main(ARGS + ["--T", "0.2", "--out", str(ext)]) == 0
    assert rows(ext)[:, 7].max() == 0                       # no contact yet
    assert cli.main(["membrane", "--restart", str(ext), "--T", "0.4", "--quiet"]) == 0
    assert rows(ext)[:, 7].max() > 0                        # the extension went through the impact
    same_run(ref, ext)
    i = info(ext)
    assert i["status"] == "finished" and i["T"] == pytest.approx(0.4) and i["steps"] == 200
    assert i["run_options"]["T"] == 0.4
    assert i["extended"] == [{"from_T": 0.2, "from_step": 100, "to_T": 0.4}]
    assert i["restarted_from_step"] == 100
    # a second extension is recorded after the first
    assert cli.main(["run", "--restart", str(ext), "--T", "0.5", "--quiet"]) == 0
    assert [e["to_T"] for e in info(ext)["extended"]] == [0.4, 0.5] and rows(ext).shape[0] == 251


def test_api_extends_a_finished_run(mpi_tmp_path):
    ref, ext = mpi_tmp_path / "ref", mpi_tmp_path / "ext"
    kw = dict(dt=2e-3, write_every=5)
    simulate("membrane", {"N": 8}, out=ref, T=0.4, **kw)
    simulate("membrane", {"N": 8}, out=ext, T=0.2, **kw)
    r = simulate(out=ext, restart=True, T=0.4)
    assert len(r.timeseries["energy"]) == 201 and r.info["extended"][0]["to_T"] == 0.4
    same_run(ref, ext)
    # an interrupted run continued to a later T, the same
    cut = mpi_tmp_path / "cut"
    with pytest.raises(Interrupted):
        simulate("membrane", {"N": 8}, out=cut, T=0.2, on_step=lambda n, row: n == 50, **kw)
    simulate(out=cut, restart=True, T=0.4)
    same_run(ref, cut)
    assert info(cut)["extended"] == [{"from_T": 0.2, "from_step": 100, "to_T": 0.4}]
    assert info(cut)["restarted_from_step"] == 50
    # a built Problem, given its options again, the same
    built = mpi_tmp_path / "built"
    simulate(membrane.problem(N=8), out=built, T=0.2, **kw)
    simulate(membrane.problem(N=8), out=built, restart=True, T=0.4, **kw)
    same_run(ref, built)
    assert info(built)["extended"] == [{"from_T": 0.2, "from_step": 100, "to_T": 0.4}]


@pytest.mark.parametrize("T,message", [
    ("0.2", "--T 0.2 is not later than the run's T = 0.2"),
    ("0.1", "--T 0.1 is not later than the run's T = 0.2"),
    ("0.301", "T = 0.301 is not a multiple of dt = 0.002"),
])
def test_cli_refuses_a_T_that_is_not_later(T, message, mpi_tmp_path, capsys):
    ext = mpi_tmp_path / "ext"
    assert cli.main(ARGS + ["--N", "4", "--T", "0.2", "--out", str(ext)]) == 0
    before = {name: text(ext / name) for name in ("run.json", "timeseries.csv", "solution.xdmf")}
    capsys.readouterr()
    assert cli.main(["membrane", "--restart", str(ext), "--T", T, "--quiet"]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert {name: text(ext / name) for name in before} == before


def test_a_finished_run_without_T_says_how_to_extend_it(mpi_tmp_path, capsys):
    ext = mpi_tmp_path / "ext"
    assert cli.main(ARGS + ["--N", "4", "--T", "0.02", "--out", str(ext)]) == 0
    capsys.readouterr()
    assert cli.main(["membrane", "--restart", str(ext), "--quiet"]) == 2
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert "already finished at T = 0.02" in err and "--T LATER" in err and len(err.strip().splitlines()) == 1


def test_api_refuses_a_T_that_is_not_later(mpi_tmp_path):
    ext = mpi_tmp_path / "ext"
    simulate("membrane", {"N": 4}, out=ext, dt=2e-3, T=0.02)
    before = text(ext / "run.json")
    with pytest.raises(RunInputError, match=r"^T = 0\.01 is not later than the run's T = 0\.02"):
        simulate(out=ext, restart=True, T=0.01)
    with pytest.raises(RunInputError, match=r"^T = 0\.02 is not later than the run's T = 0\.02"):
        simulate(membrane.problem(N=4), out=ext, restart=True, dt=2e-3, T=0.02)
    with pytest.raises(RunInputError, match="not a multiple of dt"):
        simulate(out=ext, restart=True, T=0.0301)
    assert text(ext / "run.json") == before
