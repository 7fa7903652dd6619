"""Problems: what is solved (physics only: meshes, forms, constraints, parameters).

One registry holds the declarations (:class:`ProblemSpec`) of the paper's membrane and disc, of the
sliding block (friction's closed forms), of the 1-D benchmarks with exact solutions (GetFEM's rod
``rod1d`` and Doyen-Ern-Piperno's ``bar``: :mod:`.exact`), of the 3-D ``ball`` (Hertz), of ``two_balls`` (contact between two deformable bodies) and of any
problem file a user loads
(:func:`load_file`); a new problem is one new file.
"""
from sdm_dolfinx.problems.base import Body, ContactPair, DirichletPart, Param, Problem, ProblemInputError, ProblemSpec  # noqa: F401
from sdm_dolfinx.problems.selectors import cells_where, facets_where  # noqa: F401
from sdm_dolfinx.problems.contact_pairs import slave_facets  # noqa: F401
from sdm_dolfinx.problems.registry import get, load_file, names, rebuild, register, resolve, spec_of_run  # noqa: F401
from sdm_dolfinx.problems import ball, bar, block, disc, membrane, rod1d, two_balls  # noqa: E402

__all__ = ["Body", "ContactPair", "cells_where", "facets_where", "DirichletPart", "Param", "Problem", "ProblemInputError", "ProblemSpec", "get", "load_file", "names", "slave_facets",
           "rebuild", "register", "resolve", "spec_of_run", "ball", "bar", "block", "disc", "membrane", "rod1d",
           "two_balls"]

register(membrane.SPEC)
register(disc.SPEC)
register(block.SPEC)
register(rod1d.SPEC)
register(bar.SPEC)
register(ball.SPEC)
register(two_balls.SPEC)
