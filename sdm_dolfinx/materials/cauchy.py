"""The Cauchy stress of each material from displacement gradients, in numpy: what a picture of a finished
run colours by (:func:`sdm_dolfinx.io.xdmf_reader.von_mises`), one value per cell of a P1 displacement."""
import numpy as np


def _hooke(grad, lam, mu):
    """sigma = lam tr(eps) I + 2 mu eps of displacement gradients (m, 3, 3) (plane strain: grad's third
    row and column 0)."""
    eps = 0.5 * (grad + grad.transpose(0, 2, 1))
    return 2 * mu * eps + lam * np.trace(eps, axis1=1, axis2=2)[:, None, None] * np.eye(3)


def _cauchy(pk2):
    """The Cauchy stress F S F^T / J of the displacement gradients (m, 3, 3), S = ``pk2(C, lam, mu)``."""

    def sigma(grad, lam, mu):
        F = np.eye(3) + grad
        C = F.transpose(0, 2, 1) @ F
        return F @ pk2(C, lam, mu) @ F.transpose(0, 2, 1) / np.linalg.det(F)[:, None, None]
    return sigma


def _svk(C, lam, mu):
    E = 0.5 * (C - np.eye(3))
    return lam * np.trace(E, axis1=1, axis2=2)[:, None, None] * np.eye(3) + 2 * mu * E


def _neo_hookean(C, lam, mu):
    Ci = np.linalg.inv(C)
    return mu * (np.eye(3) - Ci) + lam * 0.5 * np.log(np.linalg.det(C))[:, None, None] * Ci


#: the stress of each material a picture can show: linear (Hooke), svk, neo-hookean (Cauchy); a problem
#: file's own psi (material ``problem``) is not known here: its pictures are coloured by |u|
CAUCHY = {"linear": _hooke, "svk": _cauchy(_svk), "neo-hookean": _cauchy(_neo_hookean)}
