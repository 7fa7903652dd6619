"""data/paper: every configuration gives exactly one run of the paper's study, and the folder is current."""
import os

from mpi4py import MPI

import pytest


PAPER_DIR = os.path.join(os.path.dirname(__file__), "..", "..", "data", "paper")


@pytest.mark.parametrize("name", sorted(p for p in os.listdir(PAPER_DIR) if p.endswith(".toml")))
def test_paper_configurations_are_valid(name, tmp_path):
    """Every configuration in data/paper parses, passes the checks, and gives exactly the
    problem parameters and run options of the run that the figures study (the report)
    computes for it (nothing is run here)."""
    from sdm_dolfinx.cli import run as cli_run
    from sdm_dolfinx.paper.study import WELL_POSED, make_study
    from sdm_dolfinx.run import plan
    problem = name.split("_")[0]
    path = os.path.join(PAPER_DIR, name)
    spec, args, _ = cli_run.parse(problem, ["--config", path, "--out", str(tmp_path / "x")])
    from_file = cli_run.make_plan(spec, args, problem, MPI.COMM_SELF)
    # the study's run whose values this file gives, compared as effective values
    study = [plan(r.problem, r.params, comm=MPI.COMM_SELF, **r.options) for r in make_study().runs()
             if r.problem == problem]
    matches = [p for p in study if p.params == from_file.params and p.options == from_file.options]
    assert matches, f"{name} describes no run of the study"
    assert from_file.options["pair"] in WELL_POSED and from_file.steps >= 1


def test_paper_configurations_are_current():
    """data/paper holds exactly the study's runs (figures 1-11, 14-16, Tables 1-2):
    regenerate with scripts/gen_paper_configs.py after changing the study."""
    import importlib.util
    spec = importlib.util.spec_from_file_location(
        "gen_paper_configs", os.path.join(os.path.dirname(__file__), "..", "..", "scripts", "gen_paper_configs.py"))
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    files = gen.expected()
    assert gen.differences(files) == []
    names = " ".join(files)
    for fig in ("fig01", *(f"fig{k:02d}" for k in range(2, 12)), "table1_fig14", "table1_fig15",
                *(f"table2_level{k}" for k in range(1, 7))):
        assert fig in names, fig

