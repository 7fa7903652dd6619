"""The bound names the component it bounds (method/bound_direction.py): a floor z + u_z >= 0 declared
on u_x is refused before the run (a cube fell 17 um through it, no contact ever detected); the usual
forms, an inclined wall and scalar problems are not."""
from types import SimpleNamespace

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx.method.bound_direction import misdirected_bound

COMM = MPI.COMM_WORLD


def _problem(bound, component, gdim=3):
    x = np.random.default_rng(COMM.rank).uniform(0.0, 2.0, size=(20, 3))
    x[:, gdim:] = 0.0
    return SimpleNamespace(name="cube", shape=(gdim,), constraint_component=component, lower_bound=bound,
                           mesh=SimpleNamespace(geometry=SimpleNamespace(x=x))), x[:5].T.copy()


@pytest.mark.parametrize("bound, component, expect", [
    (lambda x: -x[2], 0, "set constraint_component = 2"),            # the floor z = 0, bounding u_x
    (lambda x: 0.5 - x[1], 2, "set constraint_component = 1"),       # the wall y = 0.5, bounding u_z
    (lambda x: -x[2], 2, None),                                      # the floor, right
    (lambda x: -x[0] - x[2], 0, None),                               # a 45 degree wall x >= -z: u_x >= -z - x
    (lambda x: np.full(x.shape[1], -0.1), 1, None),                  # a constant bound: no direction to say
    (lambda x: 0.2 * x[0] - x[1], 1, None),                          # an inclined floor, right
])
def test_misdirected_bound(bound, component, expect):
    p, cx = _problem(bound, component)
    msg = misdirected_bound(p, cx, COMM)
    if expect is None:
        assert msg is None
    else:
        assert expect in msg and len(msg.splitlines()) == 1


def test_a_scalar_problem_has_no_direction():
    p, cx = _problem(lambda x: -x[0], None)
    p.shape = ()
    assert misdirected_bound(p, cx, COMM) is None


def test_the_block_bounded_in_x_is_refused():
    """End to end: the built-in block with its foundation y = 0 bounding u_x stops before step 1."""
    from sdm_dolfinx import simulate
    from sdm_dolfinx.method.errors import DiscretisationError
    from sdm_dolfinx.problems import block
    p = block.problem(start="rest")
    p.constraint_component = 0
    with pytest.raises(DiscretisationError, match="slope -1 along y .* set constraint_component = 1"):
        simulate(p, T=1e-3, dt=1e-4)
