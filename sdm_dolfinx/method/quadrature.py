"""The quadrature degree of the discretisation's forms (A, L, B, C, M, the lumped measure).

On affine simplices (geometry degree 1) the integrands of a problem with polynomial data are
polynomials on the reference cell, and UFL's estimated degree (ffcx's default) integrates them
exactly: the runs keep it there. On curved cells (the disc's P2 geometry) or quadrilaterals the
map's Jacobian J varies over the cell and grad(phi) = J^-T grad_ref(phi), J^-1 = adj(J) / det J,
so the stiffness integrand is rational: the degree UFL estimates for A (4 for P2, 2 for P1, 6
for P1+) leaves relative errors up to 6.5e-6 in its entries. The mass-type forms (B, C, M, L
with a constant load) stay polynomial, so UFL's estimate is exact for them; the lumped measure
q ds of a curved boundary is not (|dx/ds| is a square root).

Measured (``tests/unit/test_quadrature.py`` checks it): the largest change of an entry of A, L,
B, C (or M) against degree 30, relative to the largest entry of its matrix, on the paper's
coarsest mesh (GetFEM's ``disc_P2_h4.mesh``) and on our level 1 disc (140 curved P2 triangles
each); UFL's estimate is 4 for A of P2, 2 for P1, 6 for P1+ (A alone is wrong: B, C, M, L are
exact at the estimate, < 1.5e-14):

=========  =======  =======  =======  =======  =======  =======
pair       mesh     est.     8        10       12       14
=========  =======  =======  =======  =======  =======  =======
P2/P1      GetFEM   2.2e-06  7.8e-13  3.2e-15  5.4e-15  3.6e-15
P2/P1      level 1  6.5e-06  2.2e-11  7.9e-14  3.0e-15  3.3e-15
P1+/P0     GetFEM   1.5e-07  1.1e-09  6.0e-13  4.8e-15  2.8e-15
P1+/P0     level 1  3.6e-07  6.1e-09  1.4e-11  5.2e-15  4.8e-15
P1/P0      level 1  6.5e-06  7.3e-14  2.1e-15  2.9e-15  3.7e-15
=========  =======  =======  =======  =======  =======  =======

(P1+/P1, P1/P1 and P2/P2 as the pair of the same W.) The lumped measure q ds of the level 1
disc: 2.8e-09 at UFL's estimate (5), 3.6e-15 from 10. Degree :data:`CURVED_DEGREE` = 12 puts
every entry of every pair at round-off on both meshes; finer meshes converge sooner (flatter
cells). Assembling A at 12 instead of 4 took 0.057 s instead of 0.038 s (P2, 45458 dofs).
"""
from collections.abc import Mapping
from typing import Any, Optional, Union

import ufl

from sdm_dolfinx import compat

#: the default degree of every form on non-affine cells (never below UFL's estimate of a form):
#: the entries of A, B, C, M converged to round-off on the coarsest curved disc (table above)
CURVED_DEGREE = 12
#: the largest degree accepted: basix's Xiao-Gimbutas rules (its default on triangles) end at
#: 30 (171 points); beyond it uses collapsed Gauss-Jacobi rules (256 points at 31, 2601 at
#: 100, 132651 on a tetrahedron) whose kernels cost 10 to 1000 times more for nothing: the
#: disc's entries stop changing at 12
MAX_DEGREE = 30
#: the cells whose degree-1 maps are affine
SIMPLICES = ("interval", "triangle", "tetrahedron")
#: the option's value for UFL's estimated degree on every mesh (the rule of runs before the option)
ESTIMATED = "estimated"
#: the option's value for the default (also None): ESTIMATED on affine simplices, else CURVED_DEGREE
AUTO = "auto"


def check(value: Any, label: str = "quadrature_degree") -> list[str]:
    """Messages (a list, empty when good) for a value of the quadrature option."""
    if value is None or value in (AUTO, ESTIMATED):
        return []
    if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= MAX_DEGREE:
        return []
    return [f"{label} must be an integer from 1 to {MAX_DEGREE}, {AUTO!r} or {ESTIMATED!r} (got {value!r})"]


def parse(text: str) -> Optional[Union[int, str]]:
    """The option's value of a command-line word: an integer from 1 to :data:`MAX_DEGREE`,
    :data:`AUTO` (None) or :data:`ESTIMATED`; ValueError (a phrase) otherwise."""
    word = str(text).strip()
    if word in (AUTO, ESTIMATED):
        return None if word == AUTO else word
    try:
        value = int(word)
    except ValueError:
        raise ValueError(f"{text!r} is not an integer, {AUTO} or {ESTIMATED}") from None
    if not 1 <= value <= MAX_DEGREE:
        raise ValueError(f"{value} is out of range: from 1 to {MAX_DEGREE} (the largest Xiao-Gimbutas rule of "
                         f"basix; the disc's entries stop changing at {CURVED_DEGREE})")
    return value


def is_affine(msh):
    """True when every cell of ``msh`` is an affine image of the reference cell: a simplex with
    a degree-1 geometry (P2 geometry, quadrilaterals and hexahedra are not)."""
    return compat.cell_name(msh) in SIMPLICES and compat.geometry_degree(msh) == 1


def estimated_degree(form):
    """UFL's estimated polynomial degree of ``form`` (the largest over its integrals), the
    degree ffcx uses when none is given: computed as ffcx computes it (after the pull-backs,
    the integral scaling by det J and the geometry lowering)."""
    from ufl.algorithms import compute_form_data
    data = compute_form_data(form, do_apply_function_pullbacks=True, do_apply_integral_scaling=True,
                             do_apply_geometry_lowering=True, preserve_geometry_types=(ufl.classes.Jacobian,),
                             do_apply_restrictions=True, do_append_everywhere_integrals=False)
    degrees = [itg.metadata()["estimated_polynomial_degree"] for d in data.integral_data for itg in d.integrals]
    return max(max(d) if isinstance(d, tuple) else d for d in degrees)


def effective(option, msh, forms):
    """The degree the discretisation uses for every one of its UFL ``forms`` on ``msh``: an
    integer, or :data:`ESTIMATED` (UFL's estimate of each form, ffcx's default).

    Args:
        option: None or :data:`AUTO` (:data:`ESTIMATED` on affine simplices, else
            max(:data:`CURVED_DEGREE`, the largest estimate of ``forms``): a problem whose
            polynomial integrands need more keeps them exact), :data:`ESTIMATED`, or an integer
            (that degree for every form, even below UFL's estimate).
        msh: the mesh.
        forms: the UFL forms to be compiled (only read for the automatic choice on curved cells).
    """
    if option not in (None, AUTO):
        return option
    if is_affine(msh):
        return ESTIMATED
    return max([CURVED_DEGREE] + [estimated_degree(f) for f in forms if f is not None])


def of_run(info: Mapping[str, Any]) -> Union[int, str]:
    """The effective degree recorded in a run's ``run.json`` contents (``info``): an integer or
    :data:`ESTIMATED`. A run.json without it was written before the option: UFL's estimate."""
    return info.get("quadrature_degree", ESTIMATED)


def compiler_degree(value):
    """The ``quadrature_degree`` keyword of :func:`sdm_dolfinx.compat.form` for an effective
    degree: None for :data:`ESTIMATED` (ffcx's own choice), else the integer."""
    return None if value == ESTIMATED else int(value)
