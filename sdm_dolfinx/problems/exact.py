"""Closed-form solutions of problems, for the comparison of methods against them.

A :class:`~sdm_dolfinx.problems.base.ProblemSpec` with a closed form declares
``exact=callable``: ``exact(problem) -> ExactSolution`` (the Problem carries the parameter
values in ``problem.parameters``). An :class:`ExactSolution` evaluates the displacement, the
velocity and the displacement gradient at points as dolfinx gives them (``x`` of shape (3, n),
as ``Function.interpolate`` passes), the contact stress at the contact point, and lists the
contact intervals (impact and release times). Everything is vectorised numpy: no tables.

The built-in ones: the 1-D rod of GetFEM's demo (:mod:`.rod1d`), Doyen-Ern-Piperno's bar
(:mod:`.bar`) and, through the same formula, the plane bar of ``demos/bar_problem.py``
(:class:`~sdm_dolfinx.problems.bar.PlaneBarExact`).
"""
from typing import Optional

import numpy as np


class ExactSolution:
    """The interface of a closed-form solution u(x, t) (subclasses implement the four methods).

    Attributes:
        contact_point: (3,) coordinates where the contact stress and the displacement of the
            contact are compared (a problem's probe).
        horizon: the time up to which :attr:`contact_intervals` is listed (the problem's
            default T; :meth:`intervals` gives them up to any time).
        contact_intervals: the contact phases ``[(t_start, t_end), ...]`` up to ``horizon``,
            t_start an impact, t_end a release (the contact stress is > 0 on [t_start, t_end)).
        energy: the total energy 1/2 int (rho v^2 + sigma : eps) dx, constant in time.
        period: the period of the motion, or None.
        value_shape: ``()`` for a scalar u (:meth:`displacement` returns (n,)), ``(gdim,)``
            for a vector u (returns (gdim, n)).
    """
    contact_point = np.zeros(3)
    horizon = 0.0
    energy = 0.0
    period: Optional[float] = None
    value_shape: tuple[int, ...] = ()

    def displacement(self, x, t):
        """u(x, t) at the points ``x`` (3, n): (n,) or (gdim, n)."""
        raise NotImplementedError

    def velocity(self, x, t):
        """du/dt (x, t), the shape of :meth:`displacement`."""
        raise NotImplementedError

    def strain(self, x, t):
        """The displacement gradient: du/dx (n,) for a 1-D scalar u, (gdim, gdim, n) for a vector u."""
        raise NotImplementedError

    def contact_stress(self, t):
        """The contact stress at the contact point (>= 0 when the obstacle pushes), for t a
        number or an array (same shape)."""
        raise NotImplementedError

    def intervals(self, T):
        """The contact phases ``[(t_start, t_end), ...]`` that start before ``T`` (the last
        one may end after T)."""
        raise NotImplementedError

    @property
    def contact_intervals(self):
        """:meth:`intervals` up to :attr:`horizon`."""
        return self.intervals(self.horizon)

    @property
    def impact_times(self):
        """The starts of the contact phases up to :attr:`horizon`."""
        return [a for a, _ in self.contact_intervals]

    @property
    def release_times(self):
        """The ends of the contact phases up to :attr:`horizon`."""
        return [b for _, b in self.contact_intervals]

    def in_contact(self, t):
        """True where the contact stress is > 0 (t a number or an array)."""
        return np.asarray(self.contact_stress(t)) > 0.0


def coordinate(x):
    """The first coordinate of points given as dolfinx gives them ((3, n), (gdim, n) or (n,))."""
    x = np.asarray(x, dtype=float)
    return x[0] if x.ndim == 2 else x
