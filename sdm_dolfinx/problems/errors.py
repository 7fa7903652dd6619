"""The problems' one-line error (its own module: the Problem and its Dirichlet parts both raise it)."""
from sdm_dolfinx.errors import SdmError


class ProblemInputError(SdmError, ValueError):
    """Parameter values a problem refuses (the message may join several, with '; ')."""
