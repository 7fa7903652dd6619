"""Checks before a run: the inf-sup condition (7) of a pair on a problem (:mod:`.infsup`, reported
by :mod:`.infsup_report`) and the largest Coulomb coefficient the frictional step problem stands
(:mod:`.coulomb_bound`). ``python -m sdm_dolfinx inspect`` runs them."""
from sdm_dolfinx.analysis.infsup import (DENSE_MAX, RANK_TOL, TOL, InspectError, cell_diameter, inspect, measure,
                                         operators, sweep)
from sdm_dolfinx.analysis.infsup_report import SWEEP_HEADER, plot_sweep, report, sweep_line

__all__ = ["DENSE_MAX", "RANK_TOL", "TOL", "InspectError", "cell_diameter", "inspect", "measure", "operators",
           "sweep", "SWEEP_HEADER", "plot_sweep", "report", "sweep_line"]
