"""The Hilber-Hughes-Taylor alpha method (HHT-alpha) with the constraint on U^{n+1}.

H. M. Hilber, T. J. R. Hughes, R. L. Taylor, *Improved numerical dissipation for time
integration algorithms in structural dynamics*, Earthquake Eng. Struct. Dyn. 5 (1977) 283-292
(and T. J. R. Hughes, *The Finite Element Method*, Prentice-Hall 1987, section 9.3.3): Newmark's
relations (see :mod:`~sdm_dolfinx.schemes.newmark`) with

    beta = (1 - alpha)^2 / 4,   gamma = (1 - 2 alpha) / 2,   alpha in [-1/3, 0]

and the equation of motion evaluated between t_n and t_{n+1}:

    M a^{n+1} + (1 + alpha) A U^{n+1} - alpha A U^n = L(t_{n+1+alpha}) + lam^{n+1}.

Second order, unconditionally stable, dissipative in the high frequencies for alpha < 0;
alpha = 0 is Newmark's (beta, gamma) = (1/4, 1/2). Each step is the LCP in X = U^{n+1}

    (M / (beta dt^2) + (1 + alpha) A) X = L + alpha A U^n + M Utilde / (beta dt^2) + lam.

Choices taken where the literature leaves one open:

* alpha = ``scheme_options["hht_alpha"]``, default -0.1 (a common choice: the spectral radius
  at omega dt -> infinity is (1 + alpha)/(1 - alpha) = 0.82, a mild damping of the modes the
  time step does not resolve, while the resolved ones keep second-order accuracy);
* the contact force acts at t_{n+1} with weight one (the constraint on U^{n+1}, as Newmark's),
  not weighted (1 + alpha) lam^{n+1} - alpha lam^n like the elastic force: the step stays one LCP;
* a time-dependent load enters at t_{n+1+alpha} = t_n + (1 + alpha) dt, which is HHT's
  (1 + alpha) L(t_{n+1}) - alpha L(t_n) for a load linear in time (second order otherwise);
* the acceleration state, the initial acceleration and a singular M: as Newmark's.
"""
from sdm_dolfinx.schemes.newmark import Newmark

#: the admissible range of alpha (Hilber et al.: second order and unconditionally stable)
ALPHA_RANGE = (-1.0 / 3.0, 0.0)


class HHT(Newmark):
    name = "hht"
    constrained = "U^{n+1}"
    parameters = {"hht_alpha": -0.1}

    def set_parameters(self, hht_alpha):
        lo, hi = ALPHA_RANGE
        try:
            alpha = float(hht_alpha)
        except (TypeError, ValueError):
            raise ValueError(f"hht_alpha must be a number in [-1/3, 0], got {hht_alpha!r}") from None
        if not lo <= alpha <= hi:
            raise ValueError(f"hht_alpha = {alpha:g} is out of [-1/3, 0] (HHT-alpha is second order and "
                             f"unconditionally stable there; 0 is Newmark's scheme)")
        self.hht = alpha
        self.beta = (1.0 - alpha) ** 2 / 4.0
        self.gamma = (1.0 - 2.0 * alpha) / 2.0
        self.factor = 1.0 / self.beta ** 0.5    # c_M = (factor/dt)^2
        self.load_theta = 1.0 + alpha           # L(t_{n+1+alpha})


SCHEME = HHT()
SCHEME.set_parameters(**HHT.parameters)
