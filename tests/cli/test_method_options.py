"""The method options of every run command (docs/methods.md): a value out of range, a parameter
given to a scheme or contact treatment that would ignore it, and a combination the method layer
refuses are each one line on stderr, exit status 2, nothing written."""
from mpi4py import MPI

import pytest

from sdm_dolfinx import cli

COMM = MPI.COMM_WORLD

# (argv, expected fragment of the one-line message)
BAD = [
    (["rod1d", "--hht-alpha", "-0.2"], "--hht-alpha is a parameter of scheme hht, not of scheme midpoint"),
    (["rod1d", "--scheme", "hht", "--hht-alpha", "0.5"], "--hht-alpha: must be a number in [-1/3, 0]"),
    (["rod1d", "--restitution", "0.5"], "--restitution is a parameter of scheme paoli-schatzman"),
    (["rod1d", "--penalty", "2"], "--penalty is a parameter of contact penalty"),
    (["rod1d", "--contact", "nitsche", "--nitsche-theta", "2"], "--nitsche-theta: must be one of 1, 0, -1 (got 2)"),
    (["rod1d", "--nitsche-gamma0", "5"], "--nitsche-gamma0 is a parameter of contact nitsche"),
    (["rod1d", "--contact", "penalty", "--penalty", "-1"], "--penalty: must be a finite number > 0 (got -1.0)"),
    (["rod1d", "--contact", "magic"], "invalid choice: 'magic'"),
    (["rod1d", "--constrain", "edges"], "invalid choice: 'edges'"),
    (["rod1d", "--scheme", "newmark", "--checkpoint-every", "10"], "--checkpoint-every must be left out"),
    (["membrane", "--contact", "nitsche", "--N", "4"], "declares no stress(u)"),
    (["rod1d", "--pair", "P1/P1", "--mass", "row-sum", "--scheme", "central-difference", "--dt", "0.1", "--T", "1"],
     "exceeds the CFL bound"),
    (["rod1d", "--scheme", "paoli-schatzman"], "needs M^-1"),
    (["rod1d", "--constrain", "nodes"], "constrain='nodes' is constrain='vertices'"),
    (["rod1d", "--pair", "P1/P1", "--mass", "consistent"], "mass consistent is not available for P1/P1"),
]


@pytest.mark.parametrize("argv, fragment", BAD)
def test_method_options_refused_in_one_line(argv, fragment, mpi_tmp_path, capsys):
    out = mpi_tmp_path / "run"
    assert cli.main([*argv, "--out", str(out), "--quiet"]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "error:" in err[0] and fragment in err[0], err
    assert not (out / "timeseries.csv").exists()
