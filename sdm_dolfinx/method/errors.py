"""The one error of the method layer for input it refuses before a run starts."""
from sdm_dolfinx.problems.base import ProblemInputError


class DiscretisationError(ProblemInputError):
    """A Problem, pair or scheme this method cannot discretise as given (one line, nothing
    written yet): a pair not available on the mesh's cell type, an initial state below the
    bound, a time-dependent load with a scheme that does not say when it evaluates it.
    A :class:`~sdm_dolfinx.problems.ProblemInputError` (and a ValueError): the command line
    reports it with exit status 2."""
