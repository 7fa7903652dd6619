"""The registry of (W^h, H^h) pairs (method/pairs.py): the spaces each pair builds have the
dimensions of their closed forms, and the mass treatments follow from H^h.

Closed forms on a triangulation with V vertices, E edges and F cells (Euler's formula for a
triangulated disc: V - E + F = 1, so E = V + F - 1): P1 has V dofs, the P1+ bubble adds one
per cell (F), P2 adds one per edge (E), P0 has one per cell; a vector field (d components)
has d times as many. The unit square cut into N x N squares has V = (N+1)^2, F = 2 N^2 with
one diagonal per square ('right') and V = (N+1)^2 + N^2, F = 4 N^2 with both ('crossed').
"""
from mpi4py import MPI

import pytest
from dolfinx import mesh as dmesh

from sdm_dolfinx import compat
from sdm_dolfinx.method.pairs import MASS_TREATMENTS, PAIRS, Pair, get_pair

COMM = MPI.COMM_WORLD
N = 3

#: the pairs of the paper (section 2 and 4: P1+/P0 of Lemma 2, P2/P1, and the counterexamples)
PAPER_PAIRS = {"P1+/P0", "P1/P0", "P1/P1", "P1+/P1", "P2/P1", "P2/P2"}


def counts(diagonal):
    """(V, E, F) of the N x N unit square in closed form."""
    if diagonal == "crossed":
        V, F = (N + 1) ** 2 + N ** 2, 4 * N ** 2
    else:
        V, F = (N + 1) ** 2, 2 * N ** 2
    return V, V + F - 1, F


def closed_form(space, diagonal):
    """dim of a scalar space ``("P+", 1)``, ``("P", k)`` on the square, in closed form."""
    V, E, F = counts(diagonal)
    return {("P+", 1): V + F, ("P", 1): V, ("P", 2): V + E, ("P", 0): F}[tuple(space)]


def global_dim(space):
    return space.dofmap.index_map.size_global * space.dofmap.index_map_bs


def test_registry_holds_the_papers_pairs():
    assert set(PAIRS) == PAPER_PAIRS
    for name, pair in PAIRS.items():
        assert isinstance(pair, Pair) and pair.name == name and get_pair(name) is pair


@pytest.mark.parametrize("diagonal", ["right", "crossed"])
@pytest.mark.parametrize("name", sorted(PAPER_PAIRS))
def test_dimensions_against_closed_forms(name, diagonal):
    pair = get_pair(name)
    msh = dmesh.create_unit_square(COMM, N, N, dmesh.CellType.triangle,
                                   diagonal=getattr(dmesh.DiagonalType, diagonal))
    V, E, F = counts(diagonal)
    # the mesh itself first: the closed forms rest on these counts
    msh.topology.create_entities(1)
    assert [msh.topology.index_map(d).size_global for d in (0, 1, 2)] == [V, E, F]
    cell = compat.cell_name(msh)
    for shape, factor in (((), 1), ((2,), 2)):
        W = compat.function_space(msh, pair.w_element(cell, shape))
        assert global_dim(W) == factor * closed_form(pair.w, diagonal), (name, shape)
        h_elem = pair.h_element(cell, shape)
        if pair.standard:
            assert h_elem is None                 # H^h = W^h: no second space
        else:
            H = compat.function_space(msh, h_elem)
            assert global_dim(H) == factor * closed_form(pair.h, diagonal), (name, shape)


def test_mass_treatments_follow_h():
    for pair in PAIRS.values():
        allowed = pair.allowed_masses()
        assert pair.default_mass() in allowed and set(allowed) <= set(MASS_TREATMENTS)
        if pair.h is None:
            # H^h = W^h: the consistent mass matrix of W itself, nothing to lump
            assert pair.standard and allowed == ("standard", "row-sum", "redistributed")
        elif pair.h[1] == 0:
            # P0 basis functions have disjoint supports: C is exactly diagonal
            assert allowed == ("diagonal",) and pair.default_mass() == "diagonal"
        else:
            # P1 C is not diagonal: lumped (row sums) by default, or kept (block system)
            assert allowed == ("lumped", "consistent") and pair.default_mass() == "lumped"


def test_well_posedness_statements():
    # the paper proves (7) for P1+/P0 only (Lemma 2); standard Galerkin has Ker(B) = {0}
    assert PAIRS["P1+/P0"].well_posed.startswith("proved")
    for name in ("P1/P1", "P2/P2", "P1/P0"):
        assert PAIRS[name].well_posed.startswith("no")


def test_get_pair_unknown_name():
    with pytest.raises(ValueError) as e:
        get_pair("P3/P2")
    msg = str(e.value)
    assert "'P3/P2'" in msg and "\n" not in msg
    assert all(name in msg for name in PAPER_PAIRS)
    with pytest.raises(ValueError):
        get_pair("p1+/p0")            # names are exact (case matters, as in run.json)
