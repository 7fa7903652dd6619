"""Step solvers: the bound-constrained LCP / variational inequality of one time step.

    x_c >= lb,   lam = (K x - b)_c >= 0,   lam . (x_c - lb) = 0,   (K x - b)_i = 0 off c

(paper, after eq. (14)). One concept per module: ``options`` (per-instance PETSc prefixes,
the ``vi_*`` options), ``factorisation`` (CHOLMOD / MUMPS with retries), ``augmented`` (the
sparser P2/P1 matrix to factorise), ``schur`` and ``active_set`` (the Newton systems on the
inactive set), ``semismooth`` (the default solver), ``penalty`` (the penalised contact's
solver, on the same Schur complement), ``snes_vi`` (PETSc's VI solvers) and
``registry`` (solvers by name). Every solver raises :class:`VIError` when it fails.
"""
from sdm_dolfinx.solvers.active_set import LINEAR_STRATEGIES, choose_strategy
from sdm_dolfinx.solvers.augmented import sparse_factor_matrix
from sdm_dolfinx.solvers.base import VIError
from sdm_dolfinx.solvers.factorisation import Factorisation
from sdm_dolfinx.solvers.options import VI_OPTIONS
from sdm_dolfinx.solvers.penalty import PenaltyNewton
from sdm_dolfinx.solvers.registry import VI_SOLVERS, make_vi_solver, register
from sdm_dolfinx.solvers.semismooth import SemismoothNewton
from sdm_dolfinx.solvers.snes_vi import SnesVI

__all__ = ["LINEAR_STRATEGIES", "VI_OPTIONS", "VI_SOLVERS", "VIError", "choose_strategy", "make_vi_solver",
           "sparse_factor_matrix", "register", "SemismoothNewton", "SnesVI", "Factorisation",
           "PenaltyNewton"]
