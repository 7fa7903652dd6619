"""The step solver of a Discretisation's gap rows (rigid obstacles, ``constrain="weighted"``): the
semi-smooth Newton on G x >= g (:class:`~sdm_dolfinx.solvers.gap_newton.GapNewton`, node rows against
obstacles, matrix rows for the weighted gap; with ``stiffness`` the penalty's springs on the rows), or
PETSc's SNES VI in the nodes' frames against obstacles
(:class:`~sdm_dolfinx.solvers.snes_vi_frames.FramedSnesVI`)."""
from sdm_dolfinx.solvers.gap_newton import GapNewton
from sdm_dolfinx.solvers.snes_vi_frames import FramedSnesVI


def gap_solver(d, K, vi_solver="ssn", symmetric_positive=True, options=None, factor_matrix=None, stiffness=None):
    """(the solver, its linear strategy, why) for the gap rows of the Discretisation ``d`` and the step
    matrix ``K``; the weighted rows' g is set (obstacle rows: before every step, by the caller)."""
    rows = d.obstacle_rows
    if getattr(d, "body_rows", None) is not None:          # contact between bodies (method/body_rows.py)
        solver = GapNewton(K, symmetric_positive=symmetric_positive, options=options, factor_matrix=factor_matrix,
                           surface=(d.body_rows.read, len(d.body_rows.dofs)))
        return solver, "schur", "contact pairs: surface gap rows (dense Schur complement)"
    if vi_solver != "ssn":
        rows.require_free(f"vi_solver {vi_solver}")
        solver = FramedSnesVI(K, rows.dofs, d.problem.constraint_component or 0, snes_type=vi_solver,
                              symmetric_positive=symmetric_positive, options=options)
        return solver, "lu", "obstacles: SNES VI in the nodes' frames (LU per iteration)"
    solver = GapNewton(K, None if rows is None else rows.dofs, symmetric_positive=symmetric_positive,
                       options=options, factor_matrix=factor_matrix,
                       G=None if rows is not None else d.weighted_rows.G, stiffness=stiffness)
    if rows is None:
        solver.set_rows(None, d.weighted_rows.g)
    what = "obstacles" if rows is not None else "constrain weighted"
    return solver, "schur", f"{what}: gap rows (dense Schur complement)"
