"""The restart's mapping between a kept solution.h5 and this run's node and cell order
(io/xdmf_writer.py): independent permutations of nodes and cells are recovered exactly, and
a file of another mesh is refused."""
import numpy as np
import pytest

from sdm_dolfinx.io.xdmf_writer import match_cells, match_rows


def _mesh(seed=0):
    rng = np.random.default_rng(seed)
    x = np.c_[rng.random((12, 2)), np.zeros(12)]
    cells = np.array([rng.choice(12, 3, replace=False) for _ in range(15)])
    return x, cells


def test_node_and_cell_permutations_are_recovered():
    x, cells = _mesh()
    rng = np.random.default_rng(1)
    p, q = rng.permutation(12), rng.permutation(15)     # saved node i is my node p[i]; saved cell j my cell q[j]
    inv_p = np.argsort(p)
    saved_x = x[p]
    saved_cells = inv_p[cells[q]][:, ::-1]              # the file's numbering, another vertex order in each cell
    node_map = match_rows(saved_x, x, "nodes")
    assert np.array_equal(node_map, p)
    cell_map = match_cells(saved_cells, cells, node_map, "cells")
    assert np.array_equal(cell_map, q)
    values = np.arange(15.0) * 10                        # one value per cell of this run
    assert np.array_equal(values[cell_map], values[q])


def test_cells_of_another_mesh_are_refused():
    x, cells = _mesh()
    other = cells.copy()
    other[0] = [0, 1, 2] if sorted(cells[0]) != [0, 1, 2] else [3, 4, 5]
    with pytest.raises(ValueError, match="not this run's"):
        match_cells(other, cells, np.arange(12), "cells")
