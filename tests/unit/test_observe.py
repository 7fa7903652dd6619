"""An ``observe`` callback gets a read-only State, never the Integrator (run/observe.py); the older
5-argument form still works for this release, with a one-line FutureWarning.

Facts tested: an observer cannot change the state (the arrays refuse writes and cannot be made
writeable, the State refuses new values) and the run it watches is bit-identical to the same run
unwatched; rows 0..nsteps are seen at t = n dt, with the gap the run records (gap_end); the older
form gets the PETSc vectors and the Integrator as before, with one warning on rank 0; a callable
of neither form is refused in one line.
"""
import dataclasses
import warnings

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import simulate
from sdm_dolfinx.problems import membrane
from sdm_dolfinx.run.observe import LEGACY_WARNING, ObserveError, State

COMM = MPI.COMM_WORLD
RUN = {"dt": 1e-2, "T": 0.05}


def test_observe_reads_a_state_it_cannot_change():
    """Writes into the arrays fail, the State refuses new values, and the watched run is the
    unwatched one bit for bit; rows 0..5 at t = n dt, the gap being the run's gap_end."""
    seen = []

    def look(state):
        assert type(state) is State
        with pytest.raises(dataclasses.FrozenInstanceError):
            state.U = None
        for a in (state.U, state.V, state.lam):
            assert isinstance(a, np.ndarray) and not a.flags.writeable
            with pytest.raises(ValueError):
                a[...] = 0.0
            with pytest.raises(ValueError):
                a.flags.writeable = True
        seen.append((state.n, state.t, state.U.copy(), state.vertex_gap()))

    plain = simulate(membrane.problem(N=4), **RUN)
    watched = simulate(membrane.problem(N=4), observe=look, **RUN)
    assert [s[0] for s in seen] == list(range(6)) and [s[1] for s in seen] == [n * RUN["dt"] for n in range(6)]
    for c, v in plain.timeseries.items():
        assert np.array_equal(v, watched.timeseries[c]), c
    assert np.array_equal(seen[-1][2], watched.U.array_r)
    assert [s[3] for s in seen[1:]] == list(watched.gap_end)
    assert [f.name for f in dataclasses.fields(State)] == ["n", "t", "U", "V", "lam", "discretisation"]


def test_the_older_observe_form_works_with_a_one_line_future_warning():
    """f(n, t, U, V, integ) gets what it got before (PETSc vectors, the Integrator), with one
    FutureWarning on rank 0, whose printed form is one line."""
    calls = []

    def old(n, t, U, V, integ):
        calls.append((n, t, type(U).__name__, type(integ).__name__))

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        simulate(membrane.problem(N=4), observe=old, **RUN)
    future = [w for w in caught if issubclass(w.category, FutureWarning)]
    assert len(future) == (1 if COMM.rank == 0 else 0)
    if future:
        w = future[0]
        assert str(w.message) == LEGACY_WARNING and "f(state)" in LEGACY_WARNING
        printed = warnings.formatwarning(w.message, w.category, w.filename, w.lineno)
        assert len(printed.strip().splitlines()) == 1, printed
    assert [c[0] for c in calls] == list(range(6))
    assert {c[2:] for c in calls} == {("Vec", "Integrator")}


@pytest.mark.parametrize("bad", [42, lambda a, b: None, lambda: None])
def test_observe_that_takes_neither_form_is_refused(bad):
    with pytest.raises(ObserveError, match="observe must"):
        simulate(membrane.problem(N=2), dt=1e-2, T=0.02, observe=bad)
