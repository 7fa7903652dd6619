"""The comparison's catalogue: every method is a combination of run options the package knows (the
schemes, contact treatments, pairs and masses its registries hold), with a description and the
paper it follows; ``--methods`` selects by name; the mesh size maps onto each problem's parameter."""
import pytest

from sdm_dolfinx import problems
from sdm_dolfinx import schemes
from sdm_dolfinx.method.pairs import PAIRS
from sdm_dolfinx.compare import comparison as compare
from sdm_dolfinx.compare.catalogue import CATALOGUE, METHOD_OPTIONS, METHODS, select
from sdm_dolfinx import contact
from sdm_dolfinx.method.discretisation import CONSTRAIN
from sdm_dolfinx.run import options as run_options


@pytest.mark.parametrize("method", CATALOGUE, ids=[m.name for m in CATALOGUE])
def test_every_method_is_a_known_combination_of_run_options(method):
    o = method.run_options()
    assert set(o) == set(METHOD_OPTIONS) and set(METHOD_OPTIONS) <= set(run_options.names())
    assert o["pair"] in PAIRS and o["scheme"] in schemes.names(), o
    assert o["contact"] in contact.names() and o["constrain"] in CONSTRAIN
    assert o["mass"] is None or o["mass"] in PAIRS[o["pair"]].allowed_masses()
    assert method.description and "\n" not in method.description and method.follows and method.cls


def test_select_by_name():
    assert [m.name for m in select("all")] == [m.name for m in CATALOGUE]
    assert [m.name for m in select(" hht, sdm-p2p1,hht ")] == ["hht", "sdm-p2p1"]
    with pytest.raises(ValueError, match="unknown method"):
        select("sdm-p2p1,nope")
    assert len(METHODS) == len(CATALOGUE)


def test_mesh_size_maps_onto_each_problems_parameter():
    assert compare.mesh_params(problems.get("membrane"), 0.125) == {"N": 8}
    assert compare.mesh_params(problems.get("rod1d"), 1 / 40) == {"NX": 40}
    assert compare.mesh_params(problems.get("bar"), 0.1, {"L": 2.0}) == {"L": 2.0, "NX": 20}
    assert compare.mesh_params(problems.get("disc"), 2.5) == {"h": 2.5}
    assert compare.mesh_params(problems.get("block"), 2.0) == {"nx": 10, "ny": 5}


def test_a_grid_is_checked_before_anything_runs(tmp_path):
    cmp = compare.make_comparison("rod1d", "sdm-p2p1", [0.1, 0.05], dt_ratio=0.5, T=1.0, out=tmp_path)
    assert cmp.grid == [(0.1, 0.05), (0.05, 0.025)] and len(cmp.jobs()) == 2
    assert cmp.exact is not None
    with pytest.raises(ValueError, match="whole number of steps"):
        compare.make_comparison("rod1d", "all", [0.1], [0.3], T=1.0, out=tmp_path)
    with pytest.raises(ValueError, match="unknown problem"):
        compare.make_comparison("nosuch", "all", quick=True, out=tmp_path)
    quick = compare.make_comparison("bar", "all", quick=True, out=tmp_path)
    assert all(dt == pytest.approx(h / 2) for h, dt in quick.grid) and quick.T == 3.2     # the bar's own T
