"""The linear model's range (:mod:`sdm_dolfinx.run.linear_range`): the cell rotation and strain it watches
are those of fields whose gradient is known exactly, and a run that leaves the range says so in one line.

* a rigid rotation u = W x (W skew, angle ω) has rotation ω and strain 0 in every cell, 2-D and 3-D;
  a pure strain u = E x (E symmetric) has rotation 0 and strain |E|_F; both are linear fields, which
  P1, P1+ and P2 represent exactly, so the measure is exact to round-off (tolerance 1e-12);
* the largest values are kept with the step and time they were reached, and the warning (rank 0, one
  line) names the step and the tolerance; a run that stays in range does not warn;
* a disc rolling in the bowl (Coulomb, μ = 0.5) turns by more than 0.05 rad within a quarter period and is
  warned about; the frictionless disc only translates (its contact force passes through its centre)
  and is not.
1 and 2 ranks.
"""
import warnings
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem, mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.run.linear_range import ROTATION_TOL, STRAIN_TOL, LinearRange, LinearRangeWarning

COMM = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parents[2]


def _space(gdim, element):
    if gdim == 2:
        msh = dmesh.create_unit_square(COMM, 4, 3)
    else:
        msh = dmesh.create_unit_cube(COMM, 2, 2, 3)
    cell = compat.cell_name(msh)
    elem = (compat.p1_bubble_element(cell, (gdim,)) if element == "P1+"
            else compat.element("Lagrange", cell, int(element[1]), (gdim,)))
    return compat.function_space(msh, elem)


def _state(V, grad):
    """U (PETSc, owned) of the linear field u = grad x."""
    u = fem.Function(V)
    gdim = V.mesh.geometry.dim
    u.interpolate(lambda x: grad @ x[:gdim])
    return compat.petsc_vec(u)


def _skew(gdim, w):
    if gdim == 2:
        return np.array([[0.0, -w], [w, 0.0]])
    a, b, c = w
    return np.array([[0.0, -c, b], [c, 0.0, -a], [-b, a, 0.0]])


@pytest.mark.parametrize("gdim,element", [(2, "P1"), (2, "P1+"), (2, "P2"), (3, "P1"), (3, "P2")])
def test_a_rigid_rotation_and_a_pure_strain_are_measured_exactly(gdim, element):
    V = _space(gdim, element)
    w = 0.08 if gdim == 2 else np.array([0.03, -0.05, 0.06])
    omega = float(np.linalg.norm(w))
    watch = LinearRange(V)
    watch.watch(1, 0.1, _state(V, _skew(gdim, w)))
    assert abs(watch.largest[0] - omega) < 1e-12 and abs(watch.largest[1]) < 1e-12
    E = np.diag(np.arange(1.0, gdim + 1.0)) * 0.01
    E[0, 1] = E[1, 0] = 0.02
    strain = LinearRange(V)
    strain.watch(1, 0.1, _state(V, E))
    assert abs(strain.largest[0]) < 1e-12 and abs(strain.largest[1] - np.linalg.norm(E)) < 1e-12


def test_only_a_displacement_of_the_mesh_s_dimension_is_watched():
    """A scalar field, 1-D, and a vector of another size (3 components on a 2-D mesh: its gradient is not
    square, UFL's skew part refuses it) have no rotation to watch."""
    assert LinearRange.applies((2,), 2) and LinearRange.applies((3,), 3)
    assert not any(LinearRange.applies(s, g) for s, g in (((), 2), ((1,), 1), ((3,), 2), ((2,), 3)))


def test_the_largest_is_kept_with_its_step_and_only_beyond_tolerance_warns():
    V = _space(2, "P2")
    watch = LinearRange(V)
    for n, w in enumerate((0.01, 0.5 * ROTATION_TOL, 0.02), start=1):
        watch.watch(n, 0.1 * n, _state(V, _skew(2, w)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        watch.warn()
    assert abs(watch.largest[0] - 0.5 * ROTATION_TOL) < 1e-12 and watch.where == [None, None] and not caught
    for n, w in enumerate((2 * ROTATION_TOL, 3 * ROTATION_TOL, ROTATION_TOL), start=4):
        watch.watch(n, 0.1 * n, _state(V, _skew(2, w)))
    watch.watch(7, 0.7, _state(V, 2 * STRAIN_TOL * np.eye(2) / np.sqrt(2)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        watch.warn()
        watch.warn()                                        # once per run
    assert watch.where[0][:2] == (5, 0.5) and watch.where[1][:2] == (7, 0.7)
    mine = [str(c.message) for c in caught if issubclass(c.category, LinearRangeWarning)]
    assert len(mine) == (1 if COMM.rank == 0 else 0)
    if mine:
        assert "\n" not in mine[0] and "rotated by 0.15 rad (step 5, t = 0.5" in mine[0] and "strained by 0.1 (step 7" in mine[0]


def _bowl(**friction):
    from sdm_dolfinx.problems import load_file
    from sdm_dolfinx.run import simulate
    spec = load_file(ROOT / "demos" / "bowl_problem.py")
    T0 = spec.problem(COMM).parameters["period"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = simulate(spec.problem(COMM, h=2.0), pair="P1+/P0", dt=T0 / 1000, T=0.25 * T0, **friction)
    return r, [str(c.message) for c in caught if issubclass(c.category, LinearRangeWarning)]


def test_a_disc_that_rolls_in_the_bowl_is_warned_about_and_one_that_slides_is_not():
    _, rolling = _bowl(friction="coulomb", friction_options={"mu": 0.5})
    _, sliding = _bowl()
    assert len(rolling) == (1 if COMM.rank == 0 else 0) and not sliding
    if rolling:
        assert rolling[0].startswith("a cell rotated by ") and "linear model's" in rolling[0]
