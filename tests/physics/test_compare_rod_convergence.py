"""Every method of the comparison converges to the rod's exact solution.

The 1-D rod (``rod1d``: GetFEM's demo, Dabaghi-Petrov-Pousin-Renard) has a closed form
(``sdm_dolfinx.problems.rod1d``); along h = 1/20 .. 1/160 with dt = h/2 (T = 3: one period,
one impact and one release), the relative L-infinity(0, T; L2) error of every method's
displacement field must fall, with a fitted rate. The rates measured on this grid (README,
"Which method?") are between 0.44 and 1.05; the test asserts a rate of at least 0.3 and a
finest error at most 0.6 x the coarsest (the L-infinity(L2) error of a wave with a kink is
at best O(h) for P1, and the exact-contact standard-mass methods chatter). A method
refused on a 1-D problem (``sdm-nodes``) is refused in one line.

Serial only (the 1-D rod gains nothing from two ranks; the 2-D comparison is compared on 1
and 2 ranks in tests/parallel/test_compare_ranks.py).
"""
from mpi4py import MPI

import pytest

from sdm_dolfinx.compare import comparison as compare
from sdm_dolfinx.compare.table import fit_rate

COMM = MPI.COMM_WORLD
HS = [1 / 20, 1 / 40, 1 / 80, 1 / 160]
#: the smallest fitted rate accepted, and the largest finest / coarsest error ratio
MIN_RATE, MAX_RATIO = 0.3, 0.6

pytestmark = pytest.mark.skipif(COMM.size > 1, reason="serial: the 1-D grid (2-D ranks: test_compare_ranks.py)")


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    out = tmp_path_factory.mktemp("rod-grid")
    cmp = compare.make_comparison("rod1d", "all", hs=HS, dt_ratio=0.5, T=3.0, out=out)
    return compare.run_comparison(cmp, COMM, say=lambda s: None)


def _by_method(records):
    out = {}
    for r in records:
        out.setdefault(r["method"], []).append(r)
    return out


@pytest.mark.slow
def test_every_method_converges_to_the_exact_displacement(records):
    slow = {}
    for method, rows in _by_method(records).items():
        if rows[0]["status"] == "refused":
            assert "\n" not in rows[0]["reason"] and method == "sdm-nodes", (method, rows[0]["reason"])
            continue
        assert all(r["status"] == "finished" for r in rows), (method, [r["status"] for r in rows])
        rows = sorted(rows, key=lambda r: r["h"])
        errors = [r["u_LinfL2"] for r in rows]
        fit = fit_rate([(r["h"], r["dt"], r["u_LinfL2"]) for r in rows])
        if fit is None or fit["rate"] < MIN_RATE or errors[0] > MAX_RATIO * errors[-1]:
            slow[method] = (fit and round(fit["rate"], 2), errors)
    assert not slow, f"methods not converging on the rod (rate, errors finest..coarsest): {slow}"
