"""The error every step solver raises when a step's variational inequality is not solved."""


class VIError(RuntimeError):
    """A step's variational inequality was not solved (the message says why: PETSc's or the
    active set's reason)."""
