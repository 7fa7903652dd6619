"""What a time scheme is (see :mod:`sdm_dolfinx.method.schemes`)."""


class Scheme:
    """A one-step scheme whose step is one LCP in a constrained iterate X.

    Attributes:
        name: the registry's name (the ``--scheme`` choice).
        factor: alpha = factor / dt in the step matrix alpha^2 M + A.
        constrained: the iterate the constraint is imposed on (for ``run.json``).
        load_theta: a time-dependent load of step n -> n+1 is evaluated at t_n + load_theta dt
            (None: the scheme does not say, and refuses time-dependent loads).
    """
    name = None
    factor = None
    constrained = None
    load_theta = None

    def load_time(self, t, dt):
        """The time at which the step from ``t`` to ``t + dt`` evaluates a time-dependent load."""
        if self.load_theta is None:
            raise ValueError(f"scheme {self.name!r} does not say when it evaluates a time-dependent load "
                             f"(Scheme.load_theta)")
        return t + self.load_theta * dt

    def displacement(self, x, Un):
        """U^{n+1} from the constrained iterate x and U^n (arrays)."""
        raise NotImplementedError

    def velocity(self, x, Un, Vn, alpha):
        """Vbar^{n+1} (the M formulation) from x, U^n, Vbar^n."""
        raise NotImplementedError

    def velocity_block(self, y, Vn):
        """V^{n+1} in H^h (the block formulation) from the block's second unknown y and V^n."""
        raise NotImplementedError
