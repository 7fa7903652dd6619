"""data/paper and data/validation: every configuration gives exactly one run of the report's
studies, and the folders are current."""
import os

from mpi4py import MPI

import pytest


DATA = os.path.join(os.path.dirname(__file__), "..", "..", "data")
FOLDERS = ("paper", "validation")


@pytest.mark.parametrize("folder,name", [(f, p) for f in FOLDERS for p in sorted(os.listdir(os.path.join(DATA, f)))
                                         if p.endswith(".toml")])
def test_configurations_are_valid(folder, name, tmp_path, monkeypatch):
    """Every configuration in data/paper and data/validation parses, passes the checks, and gives
    exactly the problem parameters and run options of the run that the figures study (the report)
    computes for it (nothing is run here). The memory check is the machine's, not the file's: it
    is off here (level 6 needs ~4 GB, which a busy machine may not have free at that moment)."""
    from sdm_dolfinx.run import memory
    monkeypatch.setattr(memory, "available_memory", lambda comm=None: None)
    from sdm_dolfinx.cli import run as cli_run
    from sdm_dolfinx.paper.design import WELL_POSED
    from sdm_dolfinx.report.studies import make_study
    from sdm_dolfinx.run import grouped, plan
    problem = name.split("_")[0]
    path = os.path.join(DATA, folder, name)
    spec, args, _ = cli_run.parse(problem, ["--config", path, "--out", str(tmp_path / "x")])
    from_file = cli_run.make_plan(spec, args, problem, MPI.COMM_SELF)
    # the study's run whose values this file gives, compared as effective values
    study = [plan(r.problem, r.params, comm=MPI.COMM_SELF, **grouped(r.options)) for r in make_study().runs()
             if r.problem == problem]
    matches = [p for p in study if p.params == from_file.params and p.options == from_file.options]
    assert matches, f"{name} describes no run of the study"
    assert from_file.options["pair"] in WELL_POSED and from_file.steps >= 1


def test_configurations_are_current():
    """data/paper holds exactly the paper's runs (figures 1-11, 14-16, Tables 1-2) and
    data/validation the friction runs: regenerate with scripts/gen_configs.py after changing a study."""
    import importlib.util
    spec = importlib.util.spec_from_file_location(
        "gen_configs", os.path.join(os.path.dirname(__file__), "..", "..", "scripts", "gen_configs.py"))
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    for folder in FOLDERS:
        assert gen.differences(folder, gen.expected(folder)) == [], folder
    files = gen.expected("paper")
    assert not any("friction" in n for n in files)
    assert len(gen.expected("validation")) == 10
    names = " ".join(files)
    for fig in ("fig01", *(f"fig{k:02d}" for k in range(2, 12)), "table1_fig14", "table1_fig15",
                *(f"table2_level{k}" for k in range(1, 7))):
        assert fig in names, fig

