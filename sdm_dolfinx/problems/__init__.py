"""Problems: what is solved (physics only: meshes, forms, constraints, parameters).

One registry holds the declarations (:class:`ProblemSpec`) of the paper's membrane and disc, of the
sliding block (friction's closed forms) and of any problem file a user loads (:func:`load_file`); a
new problem is one new file.
"""
from sdm_dolfinx.problems.base import Param, Problem, ProblemInputError, ProblemSpec  # noqa: F401
from sdm_dolfinx.problems.registry import get, load_file, names, rebuild, register, resolve, spec_of_run  # noqa: F401
from sdm_dolfinx.problems import block, disc, membrane  # noqa: E402

register(membrane.SPEC)
register(disc.SPEC)
register(block.SPEC)
