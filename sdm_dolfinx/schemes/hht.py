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
from sdm_dolfinx.params import Param
from sdm_dolfinx.schemes.newmark import Newmark

#: the admissible range of alpha (Hilber et al.: second order and unconditionally stable)
ALPHA_RANGE = (-1.0 / 3.0, 0.0)
#: the scheme's option (0 is Newmark's scheme)
HHT_ALPHA = Param("hht_alpha", -0.1, "the HHT scheme's alpha in [-1/3, 0] (second order and unconditionally "
                  "stable there; 0 is Newmark's scheme)", type=float, low=ALPHA_RANGE[0], high=ALPHA_RANGE[1],
                  expect="a number in [-1/3, 0]", metavar="ALPHA", optional=True)


class HHT(Newmark):
    name = "hht"
    constrained = "U^{n+1}"
    options = (HHT_ALPHA,)

    def set_parameters(self, hht_alpha):
        alpha = float(hht_alpha)
        self.hht = alpha
        self.beta = (1.0 - alpha) ** 2 / 4.0
        self.gamma = (1.0 - 2.0 * alpha) / 2.0
        self.factor = 1.0 / self.beta ** 0.5    # c_M = (factor/dt)^2
        self.load_theta = 1.0 + alpha           # L(t_{n+1+alpha})


SCHEME = HHT()
SCHEME.set_parameters(hht_alpha=HHT_ALPHA.default)
