"""A contact treatment gets a read-only StepContext, never the Integrator (contact/context.py).

Facts tested: a treatment registered here receives exactly the StepContext's five fields, none of
which leads to the Integrator (attribute paths, containers, bound methods and closures followed),
the context refuses new values, and the penalty built through it is the penalty bit for bit (the
rod's energies and contact forces over 250 steps, through its first contact).
"""
import dataclasses
import types

from mpi4py import MPI

import numpy as np
import pytest

from sdm_dolfinx import contact
from sdm_dolfinx.contact import penalty as _penalty
from sdm_dolfinx.contact.context import StepContext
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.problems import rod1d
from sdm_dolfinx.run.integrator import Integrator

COMM = MPI.COMM_WORLD


def _reaches(start, target, depth=8):
    """Whether ``target`` is reachable from ``start`` through attributes, containers, bound
    methods' ``__self__`` and closures, up to ``depth`` steps."""
    frontier, seen = [start], set()
    for _ in range(depth):
        nxt = []
        for o in frontier:
            if o is target:
                return True
            if id(o) in seen or isinstance(o, (types.ModuleType, type, np.ndarray, str, bytes)):
                continue
            seen.add(id(o))
            if isinstance(o, dict):
                nxt += list(o.values())
            elif isinstance(o, (list, tuple, set, frozenset)):
                nxt += list(o)
            nxt += list(getattr(o, "__dict__", {}).values())
            nxt += [getattr(o, "__self__", None), getattr(o, "__func__", None)]
            nxt += [c.cell_contents for c in (getattr(o, "__closure__", None) or ()) if _filled(c)]
        frontier = [o for o in nxt if o is not None]
    return any(o is target for o in frontier)


def _filled(cell):
    try:
        cell.cell_contents
    except ValueError:
        return False
    return True


@pytest.fixture
def toy():
    """The contact treatment "toy": the penalty built from whatever its factory is given (kept in
    the list the fixture yields)."""
    given = []

    def make(context, options):
        given.append(context)
        return _penalty.Penalty(context)

    contact.register("toy", make)
    try:
        yield given
    finally:
        contact._FACTORIES.pop("toy")


def _rod_run(name, steps=250):
    """The P1/P1 rod (dt = 5e-3) with contact ``name``: its Integrator, the energies
    and the contact forces after each step."""
    d = Discretisation(rod1d.problem(NX=20), "P1/P1")
    integ = Integrator(d, dt=5e-3, contact=name)
    U, V = d.initial_state()
    V = integ.initial_velocity(V)
    energy, lam = [], []
    for n in range(steps):
        integ.step(U, V, n, n * 5e-3)
        energy.append(sum(integ.energies(U, V)) + integ.contact_energy(U))
        lam.append(np.array(integ.lam))
    return integ, np.array(energy), lam


def test_a_treatment_gets_only_the_step_context(toy):
    integ, energy, lam = _rod_run("toy")
    assert len(toy) == 1 and type(toy[0]) is StepContext
    ctx = toy[0]
    assert [f.name for f in dataclasses.fields(ctx)] == ["K", "discretisation", "dt", "block", "factor_matrix"]
    assert ctx.K is integ.K and ctx.discretisation is integ.discretisation and ctx.dt == integ.dt
    assert ctx.block is False and ctx.factor_matrix is integ.factor_matrix
    assert not _reaches(ctx, integ), "the context leads to the Integrator"
    assert _reaches(ctx, integ.discretisation.problem)        # the walk does go through the fields
    with pytest.raises(dataclasses.FrozenInstanceError):
        ctx.K = None
    # the penalty through the context is the penalty
    ref, energy_ref, lam_ref = _rod_run("penalty")
    assert np.array_equal(energy, energy_ref) and all(np.array_equal(a, b) for a, b in zip(lam, lam_ref))
    assert COMM.allreduce(max(float(np.max(a, initial=0.0)) for a in lam), op=MPI.MAX) > 0.0   # it touched
    with pytest.raises(TypeError, match="takes a StepContext, got Integrator"):
        contact.make("penalty", integ)
    for i in (integ, ref):
        i.destroy()
