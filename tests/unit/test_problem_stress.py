"""The Problems' ``stress`` field and the declarations' ``exact`` entry (problems/base.py).

``stress(u)`` must be the sigma of a(u, w) = int sigma(u) : grad w dx (the Nitsche contact
treatment builds its boundary term from it): both sides are assembled for random u and w in a
P2 space of each problem's mesh and agree to 1e-12 relative to |a|'s scale sqrt(a(u, u) a(w, w)).
A problem whose a had another term (a mass, a boundary integral) or whose sigma were not
symmetric in the block's sym(grad w) form would fail. 1 and 2 ranks.
"""
from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem

from sdm_dolfinx import compat, problems
from sdm_dolfinx.problems import Problem, ProblemInputError, bar, block, disc, membrane, rod1d
from sdm_dolfinx.problems.exact import ExactSolution

COMM = MPI.COMM_WORLD

BUILD = {
    "rod1d": lambda: rod1d.problem(COMM, NX=7),
    "bar": lambda: bar.problem(COMM, NX=9, L=2.0, E=3.0, rho=0.5),
    "block": lambda: block.problem(COMM, nx=4, ny=2, nu=0.3, start="rest"),
    "disc": lambda: disc.problem(COMM, level=1),
}


def _scalar(form):
    return COMM.allreduce(fem.assemble_scalar(compat.form(form)), op=MPI.SUM)


def _random(V, seed):
    f = fem.Function(V)
    rng = np.random.default_rng(seed + 17 * COMM.rank)
    f.x.array[:] = rng.uniform(-1.0, 1.0, f.x.array.size)
    f.x.scatter_forward()                 # ghosts take their owner's value: one global function
    return f


@pytest.mark.mpi
@pytest.mark.parametrize("name", BUILD)
def test_a_is_the_integral_of_stress_against_grad(name):
    p = BUILD[name]()
    assert p.stress is not None
    cell = compat.cell_name(p.mesh)
    V = compat.function_space(p.mesh, compat.element("Lagrange", cell, 2, tuple(p.shape)))
    for seed in range(3):
        u, w = _random(V, seed), _random(V, seed + 100)
        a_uw = _scalar(p.a(u, w))
        s_uw = _scalar(ufl.inner(p.stress(u), ufl.grad(w)) * ufl.dx)
        scale = np.sqrt(abs(_scalar(p.a(u, u)) * _scalar(p.a(w, w))))
        assert scale > 0
        assert abs(a_uw - s_uw) <= 1e-12 * scale, (name, a_uw, s_uw)


def test_membrane_declares_no_stress():
    """Its constraint acts inside the domain: Nitsche's boundary term has no meaning there
    (documented in Problem's docstring), so Nitsche is refused for it."""
    assert membrane.problem(COMM, N=2).stress is None


def test_stress_must_be_callable():
    p = rod1d.problem(COMM, NX=2)
    p.stress = 1.0
    with pytest.raises(ProblemInputError, match="stress must be a callable"):
        p.validate()
    assert Problem.__dataclass_fields__["stress"].default is None


@pytest.mark.parametrize("name", ["rod1d", "bar"])
def test_declared_exact_solution(name):
    """The registered spec's ``exact`` gives an ExactSolution of the problem's parameters whose
    displacement at t = 0 is the problem's u0 and velocity its v0 (at the mesh's vertices)."""
    spec = problems.get(name)
    p = spec.problem(COMM, NX=8)
    ex = spec.exact(p)
    assert isinstance(ex, ExactSolution)
    x = p.mesh.geometry.x.T
    np.testing.assert_allclose(ex.displacement(x, 0.0), p.u0(x), atol=1e-15)
    # the rod's contact end is on the release front at t = 0: GetFEM's convention puts it
    # behind the front (u_t = -1/2), as for every t > 0
    inner = x[:, x[0] > 0]
    np.testing.assert_allclose(ex.velocity(inner, 0.0), p.v0(inner), atol=1e-15)
    assert ex.contact_intervals and ex.horizon == spec.defaults["T"]
    assert np.allclose(ex.contact_point, [*p.probe, 0.0][:3])


def test_problems_without_closed_form_declare_none():
    for name in ("membrane", "disc", "block"):
        assert problems.get(name).exact is None
