"""The run options are declared once (sdm_dolfinx.run.options) and every surface derives from the
declarations: simulate's keywords, plan, the command line's options and choices, TOML keys,
run.json. A method's options are grouped by owner (scheme_options, contact_options,
friction_options) and checked by their owner's declaration; one given to a method not chosen is
refused in one line naming its owner; the flat spellings and ``launch`` are deprecated aliases
that warn and give the same run."""
import inspect
import warnings

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import cli, contact, schemes
from sdm_dolfinx.cli import run as cli_run
from sdm_dolfinx.contact import penalty as _penalty
from sdm_dolfinx.params import Param
from sdm_dolfinx.problems import get
from sdm_dolfinx.run.result import BoundaryGapWarning
from sdm_dolfinx.run import RunInputError, grouped, launch, plan, simulate
from sdm_dolfinx.run import options as run_options
from sdm_dolfinx.run import restart as run_restart
from sdm_dolfinx.schemes.midpoint import Midpoint

COMM = MPI.COMM_WORLD


def _one_line(e):
    text = str(e.value)
    assert "\n" not in text, text
    return text


# ------------------------------------------------------------------------------ the table
def test_simulate_keywords_are_the_declared_options():
    """Every option of the table is a keyword of simulate whose default is None (the table holds
    the default: written once), plus one group per kind of owner; nothing internal is public."""
    sig = inspect.signature(simulate).parameters
    for p in run_options.TABLE:
        assert p.name in sig and sig[p.name].default is None, p.name
        assert sig[p.name].kind is inspect.Parameter.KEYWORD_ONLY
    for keyword, _ in run_options.OWNER_KINDS.values():
        assert sig[keyword].default is None
    assert "folder_seen" not in sig
    # a method's options are not keywords of their own (they are the deprecated aliases)
    owned = [p.name for p in run_options.declarations() if p.owner is not None]
    assert set(owned) == {"mu", "tresca_threshold", "penalty", "nitsche_theta", "nitsche_gamma0", "hht_alpha",
                          "restitution"}
    assert not set(owned) & set(sig)


def test_simulate_defaults_are_the_tables():
    """A run given no option records the table's defaults in run.json's run_options (flat, with
    the key names run folders have always had)."""
    r = simulate(get("membrane").problem(COMM, N=2), dt=0.01, T=0.02)
    expected = {p.name: (None if p.owner else p.default) for p in run_options.declarations()}
    assert r.info["run_options"] == {**expected, "dt": 0.01, "T": 0.02}
    assert expected["pair"] == "P1+/P0" and expected["dt"] == 1e-3 and expected["linear"] == "auto"
    # a declared problem's own defaults for pair, scheme, dt, T
    p = plan("rod1d")
    assert (p.options["pair"], p.options["dt"], p.options["T"]) == ("P2/P1", 2e-3, 12.0)


def test_restart_and_identity_come_from_the_table():
    assert run_options.RESTART_MAY_CHANGE == ("checkpoint_every",)
    assert run_restart.IDENTITY_KEYS == ("problem", "sdm_dolfinx", "pair", "mass", "scheme", "dt", "vi_solver", "linear",
                                         "material", "newton", "ranks")


def test_command_line_options_are_the_declarations():
    """One option per declared run option: flag, destination, metavar and choices."""
    parser = cli_run.build_parser(get("membrane"), "membrane")
    actions = {a.dest: a for a in parser._actions}
    for p in run_options.declarations():
        a = actions[p.name]
        assert a.option_strings == [f"--{p.option}"]
        if a.choices is not None:
            assert list(a.choices) == list(p.allowed())
        if p.metavar:
            assert a.metavar == p.metavar
    assert list(actions["scheme"].choices) == list(schemes.names())
    assert list(actions["contact"].choices) == list(contact.names())


# ------------------------------------------------------------------------- user registrations
@pytest.fixture
def springs():
    """A contact treatment registered by user code (the penalty under another name, with its own
    option ``stiffness``), and a scheme with an option; both unregistered afterwards."""
    def make(integ, options):
        return _penalty.Penalty(integ, options.get("stiffness"))

    class Scaled(Midpoint):
        name = "test-midpoint"
        options = (Param("fudge", 1.0, "a scheme option of a test", low=0.0),)

        def set_parameters(self, fudge):
            self.fudge = fudge

    contact.register("springs", make, (Param("stiffness", 1.0, "spring factor", type=float, low=0.0,
                                             low_strict=True, optional=True),))
    schemes.register(Scaled())
    try:
        yield
    finally:
        contact.unregister("springs")
        schemes._REGISTRY.pop("test-midpoint")


def test_registered_treatment_and_scheme_are_accepted_everywhere(springs, capsys, mpi_tmp_path):
    """plan and simulate accept them with their options, the command line lists them and their
    options, their values are checked by their declarations; the run is the penalty's."""
    p = plan("rod1d", {"NX": 8}, contact="springs", contact_options={"stiffness": 3.0})
    assert p.options["contact"] == "springs" and p.options["stiffness"] == 3.0
    assert plan("rod1d", scheme="test-midpoint", scheme_options={"fudge": 2.0}).options["fudge"] == 2.0
    with pytest.raises(RunInputError) as e:
        plan("rod1d", contact="springs", contact_options={"stiffness": -1.0})
    assert "stiffness must be > 0 (got -1.0)" in _one_line(e)
    with pytest.raises(RunInputError) as e:
        plan("rod1d", contact="penalty", contact_options={"stiffness": 2.0})
    assert "stiffness is a parameter of contact springs, not of contact penalty" in _one_line(e)
    parser = cli_run.build_parser(get("rod1d"), "rod1d")
    actions = {a.dest: a for a in parser._actions}
    assert "springs" in actions["contact"].choices and "test-midpoint" in actions["scheme"].choices
    assert actions["stiffness"].option_strings == ["--stiffness"] and "--contact springs" in actions["stiffness"].help
    assert actions["fudge"].option_strings == ["--fudge"]
    assert cli.main(["rod1d", "--stiffness", "2", "--out", str(mpi_tmp_path / "x"), "--quiet"]) == 2
    if COMM.rank == 0:
        err = capsys.readouterr().err
        assert "--stiffness is a parameter of contact springs, not of contact exact" in err, err
    kw = dict(pair="P1/P1", dt=5e-3, T=0.1)
    mine = simulate("rod1d", {"NX": 8}, contact="springs", contact_options={"stiffness": 3.0}, **kw)
    ref = simulate("rod1d", {"NX": 8}, contact="penalty", contact_options={"penalty": 3.0}, **kw)
    assert np.array_equal(mine.timeseries["energy"], ref.timeseries["energy"])
    assert mine.info["run_options"]["stiffness"] == 3.0 and mine.info["contact"] == "springs"


# ------------------------------------------------------------------------- the owners' rule
@pytest.mark.parametrize("options, message", [
    (dict(scheme_options={"hht_alpha": -0.1}), "hht_alpha is a parameter of scheme hht, not of scheme midpoint"),
    (dict(contact_options={"hht_alpha": -0.1}), "hht_alpha is a parameter of scheme hht: give it in scheme_options, "
                                                "not in contact_options"),
    (dict(friction="tresca", friction_options={"mu": 0.3}), "mu is a parameter of friction coulomb, not of friction "
                                                            "tresca"),
    (dict(contact="nitsche", contact_options={"penalty": 2.0}), "penalty is a parameter of contact penalty, not of "
                                                                "contact nitsche"),
    (dict(friction="coulomb"), "friction coulomb needs mu"),
    (dict(scheme="hht", scheme_options={"hht_alpha": 0.5}), "hht_alpha must be a number in [-1/3, 0] (got 0.5)"),
    (dict(contact="nitsche", contact_options={"nitsche_theta": 0.5}), "nitsche_theta must be one of 1, 0, -1"),
    (dict(scheme_options={"bogus": 1}), "unknown scheme option 'bogus' in scheme_options"),
    (dict(scheme_options={"dt": 1e-3}), "dt is an option of every run, not of a scheme: give it as dt="),
    (dict(scheme_options=[("hht_alpha", -0.1)]), "scheme_options must be a dict"),
    (dict(scheme="leapfrog"), "unknown scheme 'leapfrog'; choose one of midpoint"),
    (dict(contact="magic"), "unknown contact treatment 'magic'"),
    (dict(pair="P3/P1"), "unknown pair 'P3/P1'"),
    (dict(dt=0.0), "dt must be a positive finite number (got 0.0)"),
    (dict(bogus=1), "unknown run option(s) bogus"),
])
def test_option_refused_in_one_line_naming_its_owner(options, message):
    with pytest.raises(RunInputError) as e:
        plan("block", **options)
    assert message in _one_line(e)


def test_an_option_given_twice_is_refused():
    with pytest.warns(FutureWarning, match="hht_alpha"):
        with pytest.raises(RunInputError) as e:
            plan("block", scheme="hht", hht_alpha=-0.1, scheme_options={"hht_alpha": -0.2})
    assert "hht_alpha is given twice" in _one_line(e)


def test_grouped_is_the_inverse_of_the_flat_options():
    flat = {"pair": "P2/P1", "scheme": "hht", "hht_alpha": -0.2, "contact": "penalty", "penalty": 3.0,
            "friction": None, "mu": None}
    kw = grouped(flat)
    assert kw == {"pair": "P2/P1", "scheme": "hht", "scheme_options": {"hht_alpha": -0.2}, "contact": "penalty",
                  "contact_options": {"penalty": 3.0}}
    assert run_options.collect(kw) == {k: v for k, v in flat.items() if v is not None}


# ------------------------------------------------------------------------- deprecated aliases
@pytest.mark.parametrize("problem, params, common, flat, group", [
    ("rod1d", {"NX": 8}, dict(pair="P1/P1", scheme="hht", dt=5e-3, T=0.1), {"hht_alpha": -0.2}, "scheme_options"),
    ("rod1d", {"NX": 8}, dict(pair="P1/P1", contact="penalty", dt=5e-3, T=0.1), {"penalty": 3.0}, "contact_options"),
    ("block", {"nx": 2, "ny": 1}, dict(friction="coulomb", dt=1e-4, T=1e-3), {"mu": 0.3}, "friction_options"),
])
def test_flat_aliases_warn_and_give_the_same_run(problem, params, common, flat, group):
    with warnings.catch_warnings():
        warnings.simplefilter("error")              # the grouped form does not warn (about its options:
        warnings.simplefilter("ignore", BoundaryGapWarning)     # the P2 block's face sinks, said at its end)
        new = simulate(problem, params, **common, **{group: flat})
    name = next(iter(flat))
    with pytest.warns(FutureWarning, match=rf"simulate\({name}=...\) is deprecated: write {group}="):
        old = simulate(problem, params, **common, **flat)
    assert new.info["run_options"] == old.info["run_options"]
    for column, values in new.timeseries.items():
        assert np.array_equal(values, old.timeseries[column]), column


def test_launch_is_a_deprecated_alias_of_simulate():
    kw = dict(pair="P1/P1", dt=5e-3, T=0.05)
    new = simulate("rod1d", {"NX": 8}, **kw)
    with pytest.warns(FutureWarning, match=r"launch\(\) is deprecated: call sdm_dolfinx.simulate\(\)"):
        old = launch("rod1d", {"NX": 8}, **kw)
    assert np.array_equal(new.timeseries["energy"], old.timeseries["energy"])
    assert new.info["run_options"] == old.info["run_options"]


def test_a_built_problem_is_checked_as_a_declared_one(mpi_tmp_path):
    """simulate(Problem) checks the same run options and the same output folder."""
    problem = get("membrane").problem(COMM, N=2)
    with pytest.raises(RunInputError) as e:
        simulate(problem, dt=0.003, T=0.01)
    assert "T = 0.01 is not a multiple of dt = 0.003" in _one_line(e)
    with pytest.raises(RunInputError) as e:
        simulate(problem, {"N": 4}, dt=0.01, T=0.02)
    assert "params are the parameters of a declared problem" in _one_line(e)
    out = mpi_tmp_path / "run"
    simulate(problem, dt=0.01, T=0.02, out=out)
    with pytest.raises(RunInputError) as e:
        simulate(problem, dt=0.01, T=0.02, out=out)
    assert "overwrite" in _one_line(e)
    simulate(problem, dt=0.01, T=0.02, out=out, overwrite=True)


def test_every_option_is_documented():
    """docs/api.md names every option of the table and group keyword; docs/methods.md every
    option a built-in scheme, contact treatment or friction law declares."""
    from pathlib import Path
    docs = Path(__file__).resolve().parents[2] / "docs"
    api, methods = (docs / "api.md").read_text(), (docs / "methods.md").read_text()
    missing = [p.name for p in run_options.TABLE if f"`{p.name}`" not in api]
    missing += [kw for kw, _ in run_options.OWNER_KINDS.values() if f"`{kw}`" not in api]
    missing += [p.name for p in run_options.declarations() if p.owner and f"`{p.name}`" not in methods]
    assert not missing, missing


def test_restart_takes_the_runs_problem_parameters_and_options(mpi_tmp_path):
    """A restart continues the run in ``out`` as it was started: other parameters, another
    problem or another option (but checkpoint_every) are refused in one line, not ignored."""
    from sdm_dolfinx.run import Interrupted
    out = mpi_tmp_path / "run"
    with pytest.raises(Interrupted):
        simulate("membrane", {"N": 2}, dt=0.01, T=0.05, out=out, checkpoint_every=1, on_step=lambda n, row: n == 2)
    for kw, message in ((dict(params={"N": 3}), "its own parameters; remove params (N)"),
                        (dict(problem="disc"), "holds a 'membrane' run, not 'disc'"),
                        (dict(dt=0.02), "it cannot change dt = 0.02 (the run has 0.01)"),
                        (dict(overwrite=True), "remove overwrite")):
        with pytest.raises(RunInputError) as e:
            simulate(out=out, restart=True, **kw)
        assert message in _one_line(e)
    with pytest.raises(RunInputError) as e:
        simulate()
    assert "no problem" in _one_line(e)
    r = simulate("membrane", out=out, restart=True, checkpoint_every=2)
    assert r.info["status"] == "finished" and r.info["restarted_from_step"] == 2


def test_options_that_would_do_nothing_are_refused():
    """A step-solver choice a contact treatment ignores, and a PETSc option no step solver reads, are
    refused before anything is built (they were accepted, recorded in run.json and ignored)."""
    from sdm_dolfinx import simulate
    with pytest.raises(RunInputError, match="contact penalty has its own step solver"):
        simulate("membrane", {"N": 4}, T=0.01, contact="penalty", vi_solver="vinewtonssls")
    with pytest.raises(RunInputError, match="contact nitsche solves its steps through one factorisation"):
        simulate("disc", {"level": 1}, T=1e-4, contact="nitsche", linear="cg-amg")
    with pytest.raises(RunInputError, match="PETSc option -sdm_bogus: no step solver reads it") as e:
        simulate("membrane", {"N": 4}, T=0.01, petsc_options={"bogus": 1, "ksp_rtol": 1e-12})
    assert str(e.value).count("no step solver reads it") == 1             # ksp_rtol is a solver's
