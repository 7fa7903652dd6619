"""The discrete energy J^h (paper, Theorem 2) of a finished run, recomputed from ``state.h5``.

The potential ½ a(u, u) − l(u) is assembled from the run's own UFL forms (a hyperelastic run's
∫ ψ(C(u)) dx − l(u), ψ its material's); the kinetic energy
is ½ V̄ᵀ M V̄ with M = Bᵀ C⁻¹ B (or the standard mass) reassembled by a fresh
:class:`~sdm_dolfinx.method.discretisation.Discretisation`, or ½ ∫ ρ v·v for a run that
stored V in H^h (consistent block variant). Nothing of the running code's memory is used, so
this checks the run's own energy column independently.
"""
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx import compat, materials
from sdm_dolfinx.materials import algorithmic
from sdm_dolfinx.method import finite_strain
from sdm_dolfinx.method import quadrature
from sdm_dolfinx.method.discretisation import Discretisation
from sdm_dolfinx.mpiutil import atomic_write_text
from sdm_dolfinx.io import StateReader, read_info, read_timeseries
from sdm_dolfinx.post.rebuild_run import rebuild_problem
from sdm_dolfinx.problems import density

#: the columns of energy_recomputed.csv
ENERGY_COLUMNS = ("step", "t", "energy", "kinetic", "potential")


def recompute_energy(folder, comm=MPI.COMM_WORLD, write=True):
    """The energy J^h of every stored state of the run in ``folder``, from its files alone.

    Both energies are sums of many products that cancel (a rigid translation of the disc
    costs no elastic energy, yet every term of Uᵀ A U is large), so their difference is
    also measured against the round-off scale ½|U|ᵀ|A||U| + |U|ᵀ|L| + ½|V|ᵀ|M||V| (entrywise
    absolute values), which bounds what summation order can change. Writes
    ``folder/energy_recomputed.csv`` (rank 0) when ``write``.

    Returns:
        dict with the columns of :data:`ENERGY_COLUMNS` (arrays), ``max_rel_diff`` (the
        largest |J_recomputed − J_timeseries| over the stored steps, relative to the largest
        energy in play in the time series: |J|, the kinetic, |potential| or contact energy;
        J alone stays 0 for a body starting at rest), ``max_roundoff_ratio`` (the largest
        difference over that step's round-off scale: O(eps) when the two agree to round-off;
        0 for a state whose scale is 0, the two energies then being exactly 0),
        ``stored_dtype`` and ``rows``.
    """
    info = read_info(folder, comm)
    problem = rebuild_problem(info, comm)
    constrain = (info.get("run_options") or {}).get("constrain") or "vertices"    # a redistributed M depends on it
    disc = Discretisation(problem, info["pair"], info.get("mass"), quadrature.of_run(info), constrain=constrain)
    Vs = disc.H if info.get("mass") == "consistent" else disc.W
    reader = StateReader(folder, disc.W, Vs, comm)
    material = (info.get("run_options") or {}).get("material") or "linear"
    cols, roundoff = _energies(problem, disc, Vs, reader, comm, material)
    out = dict(cols, **_compare(cols, roundoff, read_timeseries(folder, comm)), stored_dtype=str(reader.dtype))
    if write and comm.rank == 0:
        atomic_write_text(Path(folder) / "energy_recomputed.csv", _csv_text(cols))
    comm.Barrier()
    return out


def _energies(problem, disc, Vs, reader, comm, material="linear"):
    """({column: array} of the stored states, round-off scale of each state's energy)."""
    u, v = fem.Function(disc.W), fem.Function(Vs)
    w = ufl.TestFunction(disc.W)
    # potential: 1/2 a(u, u) - l(u), the run's own UFL forms with u the stored field; a hyperelastic
    # run's int psi(C(u)) dx - l(u), psi from the material's own declaration at the run's degree
    if materials.is_linear(material):
        pot_form = disc.form(0.5 * problem.a(u, u) - ufl.action(problem.l(w), u))
    else:
        psi = algorithmic.energy_density(materials.get(material), u, problem) * ufl.dx
        pot_form = compat.form(psi - ufl.action(problem.l(w), u), quadrature_degree=finite_strain.degree(disc))
    rho = density.form(problem)
    kin_form = disc.form(0.5 * rho * ufl.inner(v, v) * ufl.dx) if Vs is not disc.W else None
    Mv = disc.M.createVecLeft() if kin_form is None else None
    cols = {c: np.zeros(len(reader)) for c in ENERGY_COLUMNS}
    absA = _abs_matrix(disc.A)
    absM = _abs_matrix(disc.M if kin_form is None else disc.C)
    absL = disc.L.copy()
    absL.abs()
    roundoff = np.zeros(len(reader))
    for i in range(len(reader)):
        reader.read(i, u, v)
        if getattr(problem, "time", None) is not None:      # a time-dependent load: l(w) at the state's time
            problem.time.value = reader.t[i]
        uu, vv = compat.petsc_vec(u), compat.petsc_vec(v)
        roundoff[i] = 0.5 * _abs_quadratic(absA, uu) + _abs_dot(absL, uu) + 0.5 * _abs_quadratic(absM, vv)
        pot = comm.allreduce(fem.assemble_scalar(pot_form), op=MPI.SUM)
        if kin_form is not None:
            kin = comm.allreduce(fem.assemble_scalar(kin_form), op=MPI.SUM)
        else:
            disc.M.mult(vv, Mv)
            kin = 0.5 * vv.dot(Mv)
        cols["step"][i], cols["t"][i] = reader.steps[i], reader.t[i]
        cols["kinetic"][i], cols["potential"][i], cols["energy"][i] = kin, pot, kin + pot
    for m in (absA, absM):
        m.destroy()
    return cols, roundoff


def _compare(cols, roundoff, ts):
    """``max_rel_diff``, ``max_roundoff_ratio`` and ``rows`` of the recomputed energies against
    the time series' energy column (at the steps both have; without its ``contact_energy``,
    the penalty or Nitsche energy, which is not recomputed)."""
    pos = {s: k for k, s in enumerate(ts["step"].astype(int))}
    rows = [k for k, s in enumerate(cols["step"].astype(int)) if s in pos]
    # a penalty or Nitsche run's energy column adds its contact_energy: compared without it
    mech = ts["energy"] - ts["contact_energy"] if "contact_energy" in ts else ts["energy"]
    ref = np.array([mech[pos[int(cols["step"][k])]] for k in rows])
    # the energies in play, not |J| alone: J stays 0 for a body starting at rest (it gave 1.7 and "nan eps")
    play = [np.max(np.abs(ts[c])) for c in ("energy", "kinetic", "potential", "contact_energy") if c in ts
            and len(ts[c])]
    scale = float(max(play, default=0.0))
    diff = np.abs(cols["energy"][rows] - ref)
    return {"max_rel_diff": _ratio(diff.max(), scale) if len(rows) else float("nan"),
            "max_roundoff_ratio": float(max(map(_ratio, diff, roundoff[rows]))) if len(rows) else float("nan"),
            "rows": len(rows)}


def _ratio(diff, scale):
    """diff / scale, with 0 / 0 = 0 (a state at rest and unloaded: both energies are exactly 0)."""
    if scale > 0:
        return float(diff / scale)
    return 0.0 if diff == 0 else float("inf")


def _csv_text(cols):
    """energy_recomputed.csv: the step as an integer, the rest at full precision."""
    lines = [",".join(ENERGY_COLUMNS)]
    for i in range(len(cols["step"])):
        lines.append(",".join([str(int(cols["step"][i]))] + [repr(float(cols[c][i])) for c in ENERGY_COLUMNS[1:]]))
    return "\n".join(lines) + "\n"


def _abs_matrix(A):
    """The matrix of entrywise absolute values |A| (same parallel layout)."""
    indptr, indices, data = A.getValuesCSR()
    B = PETSc.Mat().createAIJ(size=A.getSizes(), csr=(indptr, indices, np.abs(data)), comm=A.getComm())
    B.assemble()
    return B


def _abs_quadratic(absA, x):
    """|x|ᵀ |A| |x|."""
    ax = x.copy()
    ax.abs()
    y = absA.createVecLeft()
    absA.mult(ax, y)
    return ax.dot(y)


def _abs_dot(absb, x):
    """|x|ᵀ |b|."""
    ax = x.copy()
    ax.abs()
    return ax.dot(absb)
