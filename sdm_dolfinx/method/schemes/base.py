"""What a time scheme is (see :mod:`sdm_dolfinx.method.schemes`)."""


class Scheme:
    """A one-step scheme whose step is one LCP in a constrained iterate X.

    Attributes:
        name: the registry's name (the ``--scheme`` choice).
        factor: alpha = factor / dt in the step matrix alpha^2 M + A.
        constrained: the iterate the constraint is imposed on (for ``run.json``).
    """
    name = None
    factor = None
    constrained = None

    def displacement(self, x, Un):
        """U^{n+1} from the constrained iterate x and U^n (arrays)."""
        raise NotImplementedError

    def velocity(self, x, Un, Vn, alpha):
        """Vbar^{n+1} (the M formulation) from x, U^n, Vbar^n."""
        raise NotImplementedError

    def velocity_block(self, y, Vn):
        """V^{n+1} in H^h (the block formulation) from the block's second unknown y and V^n."""
        raise NotImplementedError
