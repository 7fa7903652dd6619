"""Making a finished run's Problem and spaces again from its ``run.json`` alone.

``run.json``'s ``problem`` entry holds the problem's name, the declared parameter values it
was built from (``args``) and, for a user's problem file, that file (``source``):
:func:`sdm_dolfinx.problems.rebuild` finds the declaration in the registry (loading the file
if needed) and builds the same Problem, so every registered problem and every problem file
is post-processed the same way.
"""
from mpi4py import MPI

from sdm_dolfinx import compat
from sdm_dolfinx.method.pairs import get_pair
from sdm_dolfinx.io import PostprocessError, read_info
from sdm_dolfinx.problems import ProblemInputError, rebuild as _rebuild_declared


def rebuild_problem(info, comm=MPI.COMM_WORLD):
    """The run's Problem, made again on ``comm`` from ``run.json``'s contents (``info``).

    Raises:
        PostprocessError: the run's problem was built by hand (no ``args`` recorded), or its
            declaration (a registered name or a problem file) cannot be found.
    """
    described = info.get("problem")
    if not isinstance(described, dict) or "name" not in described:
        raise PostprocessError("run.json has no 'problem' entry with a name: not a run of this version")
    try:
        return _rebuild_declared(described, comm)
    except ProblemInputError as e:
        raise PostprocessError(str(e)) from None


def rebuild_spaces(problem, info):
    """(W, V-space) of the run: W^h, and the space of the stored V (W^h, or H^h for the
    consistent block variant)."""
    pair = get_pair(info["pair"])
    cell = compat.cell_name(problem.mesh)
    shape = tuple(problem.shape)
    W = compat.function_space(problem.mesh, pair.w_element(cell, shape))
    if info.get("mass") == "consistent":
        return W, compat.function_space(problem.mesh, pair.h_element(cell, shape))
    return W, W


def rebuild(folder, comm=MPI.COMM_WORLD):
    """(info, problem, W, V-space) of the run in ``folder``."""
    info = read_info(folder, comm)
    problem = rebuild_problem(info, comm)
    W, Vs = rebuild_spaces(problem, info)
    return info, problem, W, Vs
