"""The problems' one-line error (its own module: the Problem and its Dirichlet parts both raise it);
defined in :mod:`sdm_dolfinx.errors`, the layer the obstacles (which a problem declares) share."""
from sdm_dolfinx.errors import ProblemInputError as ProblemInputError

__all__ = ["ProblemInputError"]
