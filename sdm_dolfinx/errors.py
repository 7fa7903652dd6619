"""The exceptions every layer shares: one base, :class:`SdmError`, for every error this package
reports in one line (bad input, a refused combination, a failed step, a folder that cannot take a
run), so that a user's script can catch them all with ``except SdmError``.

Each concept's own errors derive from these where they are defined (``RunInputError`` in
:mod:`sdm_dolfinx.run.options`, ``VIError`` in :mod:`sdm_dolfinx.solvers.base`, ...); what the
lowest layers and the file formats share is here. Imports nothing of ours.
"""


class SdmError(Exception):
    """An error this package reports in one line (its message says what and why)."""


class ProblemInputError(SdmError, ValueError):
    """Parameter values a problem (or an obstacle it declares) refuses (the message may join several,
    with '; '). Here, not in problems/, because the obstacles below the problems refuse with it too."""


class StepError(SdmError, RuntimeError):
    """A time step failed; the message names the step, the time and the cause."""


def shown(value: object) -> str:
    """``repr(value)`` for a one-line message, a numpy scalar shown as the Python number it holds
    (numpy >= 2 writes ``np.float64(0.5)`` where numpy 1 wrote ``0.5``)."""
    if type(value).__module__ == "numpy" and getattr(value, "ndim", None) == 0 and hasattr(value, "item"):
        value = value.item()
    return repr(value)
