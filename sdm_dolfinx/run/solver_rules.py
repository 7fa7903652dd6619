"""Which step-solver options a run cannot combine (:mod:`sdm_dolfinx.run.options` checks them with the
others): a choice that the solver actually used would ignore is refused, never recorded and dropped."""
from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import Any


class UnusedStrainEnergyWarning(UserWarning):
    """A problem declares ``strain_energy`` and the run's material is another: the ψ is not used."""


def treatment_solver(o: Mapping[str, Any], label: Mapping[str, str]) -> list[str]:
    """A contact treatment other than the exact one brings its own step solver (a Newton method on
    its equation, one factorisation of the step matrix): a step-solver choice would be ignored."""
    contact = o.get("contact")
    if contact in (None, "exact"):
        return []
    errors = []
    if o.get("vi_solver") not in (None, "ssn"):
        errors.append(f"{label['vi_solver']} {o['vi_solver']} solves the variational inequality of contact exact; "
                      f"contact {contact} has its own step solver: remove {label['vi_solver']}")
    if o.get("linear") not in (None, "auto", "schur"):
        errors.append(f"{label['linear']} {o['linear']}: contact {contact} solves its steps through one factorisation "
                      f"of the step matrix (schur); remove {label['linear']}")
    return errors


def snes_linear(o: Mapping[str, Any], label: Mapping[str, str]) -> list[str]:
    """PETSc's SNES VI solvers factorise their own Newton systems (MUMPS Cholesky or LU; ``-sdm_ksp_*``,
    ``-sdm_pc_*``): a linear strategy of the semi-smooth Newton would be ignored (and run.json would name it)."""
    if o.get("vi_solver") in (None, "ssn") or o.get("linear") in (None, "auto", "lu"):
        return []
    return [f"{label['vi_solver']} {o['vi_solver']!r} takes {label['linear']} 'auto' or 'lu' only: it factorises its "
            f"own Newton systems (MUMPS), and {o['linear']} is a strategy of the semi-smooth Newton (vi_solver ssn)"]


def contact_refusal(integ):
    """The refusal of a contact treatment with friction or the block variant, or of friction or a
    treatment on a problem without constrained vertices (they would do nothing), or None."""
    d = integ.discretisation
    if d.num_constraints == 0 and (integ.friction is not None or integ.contact != "exact"):
        what = f"friction {integ.friction.law}" if integ.friction is not None else f"contact {integ.contact}"
        return (f"{what} acts at the constrained vertices, and problem {d.problem.name!r} has none (contact "
                f"switched off?): remove it")
    if integ.contact == "exact":
        return None
    if integ.friction is not None:
        return f"friction needs contact 'exact' (the frictional step is a VI), not {integ.contact!r}"
    if integ.block:
        return (f"contact {integ.contact!r} is written in the M formulation; mass 'consistent' solves the "
                f"(U, V) block system: use mass 'lumped'")
    return None


def finite_strain_refusal(integ, vi_solver, linear):
    """The refusal of a hyperelastic material (``integ.finite_strain``) with what its step does not take yet,
    or of ``newton modified`` with the linear material (it would be ignored), or None."""
    from sdm_dolfinx.problems.base import EQUILIBRIUM
    from sdm_dolfinx.problems.block import StaticStart
    from sdm_dolfinx.run.finite_strain_step import NEWTON, STRATEGIES
    d, ts, m = integ.discretisation, integ.time_scheme, integ.finite_strain
    if integ.newton not in NEWTON:
        return f"unknown newton {integ.newton!r}; choose one of {', '.join(NEWTON)}"
    if m is None:
        return (None if integ.newton == "full" else
                f"newton {integ.newton!r} is the tangent of a hyperelastic material's step; material linear has a "
                f"constant step matrix: remove newton")
    where = f"material {m!r}"
    p = d.problem
    if ts.finite_strain is None:
        return (f"{where} takes the midpoint scheme (energy-momentum), or backward-euler, newmark or hht for "
                f"comparison; scheme {integ.scheme!r} has no finite-strain step yet")
    not_yet = [(integ.contact != "exact", f"contact {integ.contact!r}"),
               (integ.block, "mass 'consistent' (the (U, V) block system)"),
               (vi_solver != "ssn", f"vi_solver {vi_solver!r}"),
               (linear not in ("auto", *STRATEGIES), f"linear {linear!r} (use {', '.join(STRATEGIES)})"),
               (bool(p.contact_pairs), "contact pairs (the rows between bodies)"),
               (bool(p.bodies), "a mesh of several bodies (the per-body columns)"),
               ((isinstance(p.u0, str) and p.u0 == EQUILIBRIUM) or isinstance(p.u0, StaticStart),
                "the equilibrium start (the linear model's static solution, not the material's: start the problem "
                "unstressed, with the built-in problems' --start option)")]
    for refused, what in not_yet:
        if refused:
            return f"{where} does not take {what} yet: use material linear for it"
    return None


def warn_unused_strain_energy(integ):
    """Warn in one line (rank 0) when the problem declares ``strain_energy`` and the run's material is another
    hyperelastic one: that ψ does not enter the run, the material's own law does. (The linear model, the
    default, is not warned about: a problem may offer its ψ beside a(u, w), as demos/pushed_block_problem.py
    does, and run.json names the material.)"""
    d = integ.discretisation
    material = integ.finite_strain
    if getattr(d.problem, "strain_energy", None) is None or material in (None, "problem") or d.comm.rank != 0:
        return
    # warn_explicit with no source file: one line ("sdm_dolfinx:0: UnusedStrainEnergyWarning: ...")
    warnings.warn_explicit(f"problem {d.problem.name!r} declares strain_energy, which material {material!r} does not "
                           f"use: material 'problem' runs it", UnusedStrainEnergyWarning, "sdm_dolfinx", 0)
