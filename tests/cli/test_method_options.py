"""The method options of every run command (docs/methods.md): a value out of range, a parameter
given to a scheme or contact treatment that would ignore it, and a combination the method layer
refuses are each one line on stderr, exit status 2, nothing written."""
from mpi4py import MPI

import pytest

from sdm_dolfinx import cli

COMM = MPI.COMM_WORLD

PENALTY_TOO_LARGE = "--penalty: must be at most 1e+12 (above, the springs' compliance 1/penalty is lost"
GAMMA0_TOO_LARGE = "--nitsche-gamma0: must be at most 1e+06 (above, a step's Newton residual stalls"

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
    # out of the range where the treatment still means what it says (the reason is in the message)
    (["rod1d", "--contact", "penalty", "--penalty", "1e13"], PENALTY_TOO_LARGE),
    (["rod1d", "--contact", "penalty", "--penalty", "1e308"], PENALTY_TOO_LARGE),
    (["rod1d", "--contact", "nitsche", "--nitsche-gamma0", "1e7"], GAMMA0_TOO_LARGE),
    (["rod1d", "--contact", "nitsche", "--nitsche-gamma0", "1e308"], GAMMA0_TOO_LARGE),
    # a misspelt option is named first, not the option it leaves without its owner
    (["block", "--fricton", "coulomb", "--mu", "0.2"], "unrecognised option '--fricton'; did you mean --friction?"),
    (["block", "--contact", "penalty", "--penalti", "10"], "unrecognised option '--penalti'; did you mean --penalty?"),
]


@pytest.mark.parametrize("argv, fragment", BAD)
def test_method_options_refused_in_one_line(argv, fragment, mpi_tmp_path, capsys):
    out = mpi_tmp_path / "run"
    assert cli.main([*argv, "--out", str(out), "--quiet"]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "error:" in err[0] and fragment in err[0], err
    assert not (out / "timeseries.csv").exists()


def test_the_bounds_say_why_through_the_api():
    from sdm_dolfinx import simulate
    from sdm_dolfinx.run import RunInputError
    with pytest.raises(RunInputError, match=r"^penalty must be at most 1e\+12 \(above, .*round-off.*\(got 1e\+13\)$"):
        simulate("rod1d", T=0.1, contact="penalty", contact_options={"penalty": 1e13})
    with pytest.raises(RunInputError, match=r"^nitsche_gamma0 must be at most 1e\+06 \(above, .*1e-8.*\(got 1e\+09\)$"):
        simulate("rod1d", T=0.1, contact="nitsche", contact_options={"nitsche_gamma0": 1e9})


def test_coulomb_failure_names_the_bound(mpi_tmp_path, capsys):
    """The block's Coulomb step problem with mu = 3 fails (at step 1 here, at step 331 on CI's
    dolfinx 0.9: which step first breaks the non-unique step problem is round-off, not physics):
    the one line says mu is above the bound measured as inspect --coulomb-bound measures it, and
    names that command (it said
    only that Newton did not converge); before the first step a one-line warning already named the
    bound (the bound is sufficient, not sharp: a warning, not a refusal). With mu = 0.3 (below it)
    the run says nothing."""
    import re
    from sdm_dolfinx.analysis.coulomb_bound import coulomb_bound
    from sdm_dolfinx.problems import block
    import warnings
    out = mpi_tmp_path / "run"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert cli.main(["block", "--friction", "coulomb", "--mu", "3", "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    bound = coulomb_bound(block.problem(), "P2/P1", 1e-4)["mu_c"]
    if COMM.rank == 0:
        error = err.strip()
        warning = " ".join(str(w.message) for w in caught if type(w.message).__name__ == "CoulombBoundWarning")
        assert len(error.splitlines()) == 1 and re.match(r"python -m sdm_dolfinx block: error: step \d+ \(t = ", error), err
        m = re.search(r"mu = 3 is above (\S+), the largest Coulomb coefficient", error)
        assert m and float(m.group(1)) == float(f"{bound:.3g}"), err
        assert f"mu = 3 is above {bound:.3g}, the Coulomb bound measured on this run's step problem" in warning
        assert "--coulomb-bound" in warning
        assert "inspect --problem block --pair P2/P1 --coulomb-bound --dt 0.0001" in err


def test_a_coulomb_coefficient_below_the_bound_runs_without_a_word(mpi_tmp_path, capsys):
    """mu = 0.3 on the block (its measured bound about 2): no warning, the run goes through."""
    import warnings
    out = mpi_tmp_path / "run"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert cli.main(["block", "--friction", "coulomb", "--mu", "0.3", "--T", "2e-3", "--out", str(out),
                         "--quiet"]) == 0
    assert not [w for w in caught if type(w.message).__name__ == "CoulombBoundWarning"]
