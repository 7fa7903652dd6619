"""Post-processing: reading runs back, energy, transfer between meshes, norms, the inf-sup
measurement and pictures. Public names (the layers above import only these).

One concept per module: :mod:`.read` (run.json, timeseries.csv, state.h5), :mod:`.rebuild_run`
(a run's Problem and spaces from its run.json), :mod:`.energy`, :mod:`.transfer`
(non-matching meshes), :mod:`.norms`, :mod:`.infsup` and :mod:`.infsup_report` (condition
(7)), :mod:`.render` (pictures; :mod:`.xdmf` and :mod:`.render_mpl` behind it).
"""
import importlib

from sdm_dolfinx.post.energy import ENERGY_COLUMNS, recompute_energy
from sdm_dolfinx.post.infsup import (DENSE_MAX, RANK_TOL, TOL, InspectError, cell_diameter, inspect, measure,
                                     operators, sweep)
from sdm_dolfinx.post.infsup_report import SWEEP_HEADER, plot_sweep, report, sweep_line
from sdm_dolfinx.post.norms import convergence_rate, h1_error, h1_norm
from sdm_dolfinx.post.read import PostprocessError, StateReader, read_info, read_timeseries
from sdm_dolfinx.post.rebuild_run import rebuild, rebuild_problem, rebuild_spaces
from sdm_dolfinx.post.transfer import evaluate_nonmatching, interpolate_by_points, interpolate_nonmatching

__all__ = ["render", "ENERGY_COLUMNS", "recompute_energy",
           "DENSE_MAX", "RANK_TOL", "TOL", "InspectError", "cell_diameter", "inspect", "measure", "operators",
           "sweep", "SWEEP_HEADER", "plot_sweep", "report", "sweep_line",
           "convergence_rate", "h1_error", "h1_norm",
           "PostprocessError", "StateReader", "read_info", "read_timeseries",
           "rebuild", "rebuild_problem", "rebuild_spaces",
           "evaluate_nonmatching", "interpolate_by_points", "interpolate_nonmatching"]


def __getattr__(name):
    # ``render`` is imported on first use, not here: ``python -m sdm_dolfinx.post.render`` would
    # otherwise find it already imported (runpy's warning) and it needs no dolfinx at all
    if name == "render":
        return importlib.import_module("sdm_dolfinx.post.render")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
