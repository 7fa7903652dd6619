"""The finite-strain patch test and the small-strain limit against closed forms: the report's checks 2 and 3
of the section "Finite strain" (:mod:`sdm_dolfinx.report.finite_strain_entry`) and of
tests/physics/test_finite_strain.py.

:func:`stretched_block`: the unit square (plane strain, P2/P1, Lamé (2, 1), density 1) on a distorted mesh,
stretched along x by u_x = rate t x (Dirichlet parts on the sides x = 0 and x = 1, x only) with u_y = 0 on
the top and bottom: the homogeneous deformation F = diag(1 + rate t, 1) is the exact solution (P_xy = 0
on every side, d^2u/dt^2 = 0), and the reaction on the side x = 1 is, for each step from stretch l0 to
l1, the energy-momentum stress :func:`closed_form_reaction` in closed form. :func:`patch` measures both;
:func:`small_strain` the departure of each material's reaction from the linear model's at small stretches,
which must be O(strain).
"""
import time

from mpi4py import MPI

import numpy as np
from dolfinx import mesh as dmesh

from sdm_dolfinx.problems import DirichletPart
from sdm_dolfinx.run import simulate
from sdm_dolfinx.validation.finite_strain import LAM, MU, free_body

#: the patch test's rate (u_x = RATE t x) and time step: 10 steps to the stretch 1.5
RATE, DT, STEPS = 0.5, 0.1, 10
#: the small-strain study's final strains
STRAINS = (1e-3, 1e-2, 1e-1)


def closed_form_reaction(material, l0, l1, lam=LAM, mu=MU):
    """The x-reaction on the side x = 1 (height 1) of the step from stretch l0 to l1 under uniaxial plane
    strain F = diag(l, 1): P_alg_xx = F_mid_xx S_alg_xx of the energy-momentum stress (Simo-Tarnow's for
    svk, Gonzalez's discrete gradient for neo-Hookean; linear: Hooke's (lam + 2 mu) (l_mid - 1))."""
    if material == "linear":
        return (lam + 2 * mu) * (0.5 * (l0 + l1) - 1.0)

    def psi(c):                 # of C_xx = c (C_yy = 1)
        if material == "svk":
            e = 0.5 * (c - 1.0)
            return 0.5 * lam * e ** 2 + mu * e ** 2
        lnJ = 0.5 * np.log(c)
        return 0.5 * mu * (c - 1.0) - mu * lnJ + 0.5 * lam * lnJ ** 2

    def S(c):                   # S_xx = 2 dpsi/dC_xx
        if material == "svk":
            return (lam + 2 * mu) * 0.5 * (c - 1.0)
        return mu * (1.0 - 1.0 / c) + lam * 0.5 * np.log(c) / c
    c0, c1 = l0 ** 2, l1 ** 2
    s = S(0.5 * (c0 + c1))
    if material != "svk":       # Gonzalez's correction, dC = diag(c1 - c0, 0)
        s += 2.0 * (psi(c1) - psi(c0) - 0.5 * s * (c1 - c0)) / (c1 - c0)
    return 0.5 * (l0 + l1) * s


def stretched_block(rate=RATE, comm=MPI.COMM_WORLD):
    """The unit square, its inner vertices moved by up to 0.3 h (a distorted mesh, the same on any number of
    ranks), stretched along x by u_x = rate t x (see the module)."""
    n = 4
    msh = dmesh.create_unit_square(comm, n, n)
    x = msh.geometry.x
    inner = (x[:, 0] > 1e-12) & (x[:, 0] < 1 - 1e-12) & (x[:, 1] > 1e-12) & (x[:, 1] < 1 - 1e-12)
    x[inner, 0] += 0.3 / n * np.sin(37.0 * x[inner, 0] + 17.0 * x[inner, 1])
    x[inner, 1] += 0.3 / n * np.cos(23.0 * x[inner, 0] + 41.0 * x[inner, 1])
    side = lambda pred: (lambda m: dmesh.locate_entities_boundary(m, 1, pred))          # noqa: E731
    parts = [DirichletPart("left", side(lambda x: np.isclose(x[0], 0.0)), lambda x, t: 0.0, components=(0,)),
             DirichletPart("right", side(lambda x: np.isclose(x[0], 1.0)), lambda x, t: rate * t,
                           velocity=lambda x, t: rate, components=(0,)),
             DirichletPart("sides", side(lambda x: np.isclose(x[1], 0.0) | np.isclose(x[1], 1.0)),
                           lambda x, t: 0.0, components=(1,))]
    return free_body(msh, lambda x: np.zeros((2, x.shape[1])), lambda x: np.array([rate * x[0], 0.0 * x[0]]),
                     parts, columns=())


def stretch(material, rate=RATE, comm=MPI.COMM_WORLD):
    """The stretched block with ``material`` for :data:`STEPS` steps of :data:`DT`: (its Result, the
    closed-form reactions of its steps)."""
    r = simulate(stretched_block(rate, comm), pair="P2/P1", material=material, dt=DT, T=STEPS * DT)
    t = np.asarray(r.timeseries["t"])
    expected = np.array([closed_form_reaction(material, 1 + rate * t0, 1 + rate * t1) for t0, t1 in zip(t[:-1], t[1:])])
    return r, expected


def patch(material, comm=MPI.COMM_WORLD):
    """The patch test's row: the largest error of u against (rate t x, 0) at every dof at the end, the
    largest relative error of the reaction against the closed form over the steps (collective)."""
    t0 = time.perf_counter()
    r, expected = stretch(material, comm=comm)
    d = r.discretisation
    n = len(r.U.array) // 2
    xdof = d.W.tabulate_dof_coordinates()[:n]
    u = r.U.array.reshape(-1, 2)
    err_u = comm.allreduce(float(np.max(np.abs(np.c_[u[:, 0] - RATE * STEPS * DT * xdof[:, 0], u[:, 1]]),
                                        initial=0.0)), op=MPI.MAX)
    got = np.asarray(r.timeseries["reaction_right_x"][1:])
    return {"material": material, "stretch": 1 + RATE * STEPS * DT, "err_u": err_u,
            "err_reaction": float(np.max(np.abs(got / expected - 1))), "final_reaction": float(got[-1]),
            "linear_reaction": float(closed_form_reaction("linear", 1 + RATE * (STEPS - 1) * DT,
                                                          1 + RATE * STEPS * DT)),
            "seconds": time.perf_counter() - t0}


def small_strain(material, comm=MPI.COMM_WORLD):
    """The last step's reaction of ``material`` against the linear run's at the final strains
    :data:`STRAINS`: the relative departures and the slope of their log-log fit (1: O(strain))."""
    dev = []
    for strain in STRAINS:
        rate = strain / (STEPS * DT)
        lin = np.asarray(stretch("linear", rate, comm)[0].timeseries["reaction_right_x"])[-1]
        fs = np.asarray(stretch(material, rate, comm)[0].timeseries["reaction_right_x"])[-1]
        dev.append(float(fs / lin - 1))
    slope = float(np.polyfit(np.log(STRAINS), np.log(np.abs(dev)), 1)[0])
    return {"material": material, "strains": list(STRAINS), "departures": dev, "slope": slope}
