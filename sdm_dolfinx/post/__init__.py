"""Post-processing of finished runs: energy recomputed, transfer between meshes, norms, the
comparison's metrics and pictures. Public names (the layers above import only these).

One concept per module: :mod:`.rebuild_run` (a run's Problem and spaces from its run.json),
:mod:`.energy`, :mod:`.transfer` (non-matching meshes), :mod:`.norms`, :mod:`.metrics` (the
method comparison's errors), :mod:`.render` (pictures; :mod:`.render_mpl` behind it). The files
are read with :mod:`sdm_dolfinx.io`.
"""
import importlib

from sdm_dolfinx.post.energy import ENERGY_COLUMNS, recompute_energy
from sdm_dolfinx.post.norms import convergence_rate, h1_error, h1_norm
from sdm_dolfinx.post.rebuild_run import rebuild, rebuild_problem, rebuild_spaces
from sdm_dolfinx.post.transfer import evaluate_nonmatching, interpolate_by_points, interpolate_nonmatching

__all__ = ["render", "ENERGY_COLUMNS", "recompute_energy",
           "convergence_rate", "h1_error", "h1_norm",
           "rebuild", "rebuild_problem", "rebuild_spaces",
           "evaluate_nonmatching", "interpolate_by_points", "interpolate_nonmatching"]


def __getattr__(name):
    # ``render`` is imported on first use, not here: ``python -m sdm_dolfinx.post.render`` would
    # otherwise find it already imported (runpy's warning) and it needs no dolfinx at all
    if name == "render":
        return importlib.import_module("sdm_dolfinx.post.render")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
