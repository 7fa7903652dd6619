"""Observers: probes, the CSV time series, run.json and XDMF fields.

Only rank 0 writes CSV/JSON; XDMF is written collectively. Scalars are reduced over ranks.
"""
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
from dolfinx import fem

from sdm_dolfinx import compat
from sdm_dolfinx.mpiutil import gather_blocks, gather_vec, write_json  # noqa: F401  (write_json: re-exported)

class PointProbe:
    """Value of a W-function at a point, on every rank (the lowest rank owning it evaluates)."""

    def __init__(self, V, point, component=None):
        msh = V.mesh
        self.comm = msh.comm
        x = np.zeros((1, 3))
        x[0, :len(point)] = point
        self.x = x
        cells = compat.colliding_cells(msh, compat.bounding_box_tree(msh), x).links(0)
        nowned = msh.topology.index_map(msh.topology.dim).size_local
        cells = cells[cells < nowned]
        rank = self.comm.rank if len(cells) else self.comm.size
        self.owner = self.comm.allreduce(rank, op=MPI.MIN)
        if self.owner == self.comm.size:
            raise ValueError(f"probe point {tuple(point)} lies outside the mesh")
        self.cell = cells[:1]
        self.component = component
        self.f = fem.Function(V)

    def __call__(self, vec):
        """Evaluate the W-vector ``vec`` (owned entries) at the probe point."""
        n = len(vec.array)
        self.f.x.array[:n] = vec.array
        self.f.x.scatter_forward()
        val = 0.0
        if self.comm.rank == self.owner:
            v = self.f.eval(self.x, self.cell).reshape(-1)
            val = float(v[self.component or 0])
        return self.comm.allreduce(val, op=MPI.SUM)


class ConstraintProbe:
    """The constrained vertex nearest to a point: its stress lam_i / m_i (m_i the lumped measure)."""

    def __init__(self, discretisation, point):
        self.comm = discretisation.comm
        p = np.zeros(3)
        p[:len(point)] = point
        d = np.linalg.norm(discretisation.cx.T - p[None, :], axis=1) if discretisation.cx.shape[1] else np.zeros(0)
        dmin = float(d.min()) if d.size else np.inf
        best = self.comm.allreduce((dmin, self.comm.rank), op=MPI.MINLOC)
        self.owner = best[1]
        self.index = int(np.argmin(d)) if (self.comm.rank == self.owner and d.size) else -1
        x = discretisation.cx[:, self.index].copy() if self.index >= 0 else np.zeros(3)
        self.vertex = self.comm.allreduce(x, op=MPI.SUM)
        self.measure = discretisation.cmeasure

    def __call__(self, lam):
        val = lam[self.index] / self.measure[self.index] if self.index >= 0 else 0.0
        return self.comm.allreduce(float(val), op=MPI.SUM)


class CSVWriter:
    """timeseries.csv, one complete line per step, flushed (a killed run keeps whole rows)."""

    def __init__(self, path, columns, comm, append=False):
        self.comm, self.columns = comm, tuple(columns)
        self.fh = None
        if comm.rank == 0:
            self.fh = open(path, "a" if append else "w", buffering=1)
            if not append:
                self.fh.write(",".join(self.columns) + "\n")

    def write(self, row):
        """Append one row (a dict column -> value) and flush it (rank 0 only)."""
        if self.fh is not None:
            self.fh.write(",".join(_fmt(row[c]) for c in self.columns) + "\n")
            self.fh.flush()

    def close(self):
        """Close the file (rank 0 only)."""
        if self.fh is not None:
            self.fh.close()
            self.fh = None


def _fmt(v):
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    return repr(float(v))


class StateWriter:
    """state.h5: the native dof vectors of U and V every K steps, for post-processing.

    XDMF shows ParaView vertex interpolants; this file keeps the exact coefficients, in the
    run's global dof numbering, together with each dof's coordinates (so that a reader on
    any number of ranks can match them) and the mesh fingerprint. Written by rank 0 with
    (serial) h5py after a gather; datasets ``U``, ``V`` (one row per write), ``t``, ``step``;
    groups ``W`` and ``V_space`` hold ``dof_coordinates`` and ``block_size``.
    """

    def __init__(self, path, discretisation, integrator, fingerprint, append=False, last_step=None):
        self.comm, self.path = discretisation.comm, Path(path)
        vspace = discretisation.H if integrator.block else discretisation.W
        coords = {name: gather_blocks(sp, sp.tabulate_dof_coordinates(), self.comm)
                  for name, sp in (("W", discretisation.W), ("V_space", vspace))}
        bs = {"W": discretisation.W.dofmap.index_map_bs, "V_space": vspace.dofmap.index_map_bs}
        if self.comm.rank == 0:
            import h5py
            if append and self.path.exists():
                with h5py.File(self.path, "a") as h5:
                    keep = int(np.searchsorted(h5["step"][:], last_step, side="right"))
                    for name in ("U", "V", "t", "step"):
                        h5[name].resize(keep, axis=0)
            else:
                with h5py.File(self.path, "w") as h5:
                    for name in ("W", "V_space"):
                        g = h5.create_group(name)
                        g.create_dataset("dof_coordinates", data=coords[name])
                        g.attrs["block_size"] = bs[name]
                    nu = coords["W"].shape[0] * bs["W"]
                    nv = coords["V_space"].shape[0] * bs["V_space"]
                    # float64: h5py's default float32 would lose half the digits
                    h5.create_dataset("U", shape=(0, nu), maxshape=(None, nu), chunks=(1, nu), dtype="f8")
                    h5.create_dataset("V", shape=(0, nv), maxshape=(None, nv), chunks=(1, nv), dtype="f8")
                    h5.create_dataset("t", shape=(0,), maxshape=(None,), dtype="f8")
                    h5.create_dataset("step", shape=(0,), maxshape=(None,), dtype="i8")
                    h5.attrs["V_is"] = "V in H^h (block system)" if integrator.block else "Vbar in W^h"
                    for k, v in fingerprint.items():
                        h5.attrs["mesh_" + k] = v
        self.comm.Barrier()

    def write(self, U, V, step, t):
        """Gather U and V to rank 0 and append them, with the step and time, to state.h5."""
        u, v = gather_vec(U, self.comm), gather_vec(V, self.comm)
        if self.comm.rank == 0:
            import h5py
            with h5py.File(self.path, "a") as h5:
                n = h5["t"].shape[0]
                for name, val in (("U", u), ("V", v), ("t", t), ("step", step)):
                    h5[name].resize(n + 1, axis=0)
                    h5[name][n] = val


class XDMFWriter:
    """solution.xdmf: displacement, velocity, contact stress and active set at vertices.

    Fields are written as explicit P1 interpolants, which every dolfinx version and
    ParaView's Xdmf3 reader accept.
    """

    def __init__(self, path, discretisation, integrator, append=False):
        self.discretisation, self.integ = discretisation, integrator
        msh = discretisation.problem.mesh
        self.path, self.comm = path, msh.comm
        if not append:
            with compat.xdmf_file(msh.comm, path, "w") as f:
                f.write_mesh(msh)
        self.uW = fem.Function(discretisation.W)
        self.vsrc = fem.Function(discretisation.H if integrator.block else discretisation.W)
        self.u1 = fem.Function(discretisation.P1, name="displacement")
        self.v1 = fem.Function(discretisation.P1, name="velocity")
        self.s1 = fem.Function(discretisation.Q1, name="contact_stress")
        self.a1 = fem.Function(discretisation.Q1, name="active")

    def write(self, U, V, lam, active, t):
        """Write the displacement, velocity, contact stress and active set at time t (collective).

        The fields are interpolated into P1 (vertex values) so that dolfinx 0.5 and 0.10 write the same file;
        the contact stress is each constrained vertex's multiplier divided by its lumped measure.
        """
        d = self.discretisation
        self.uW.x.array[:len(U.array)] = U.array
        self.uW.x.scatter_forward()
        self.u1.interpolate(self.uW)
        self.vsrc.x.array[:len(V.array)] = V.array
        self.vsrc.x.scatter_forward()
        self.v1.interpolate(self.vsrc)
        for f, vals in ((self.s1, lam / np.where(d.cmeasure > 0, d.cmeasure, 1.0)),
                        (self.a1, active.astype(float))):
            f.x.array[:] = 0.0
            f.x.array[d.q1_of_c] = vals
            vec = compat.petsc_vec(f)
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        # opened and closed at every write: HDF5 keeps an open file's metadata in memory, so a
        # run killed with SIGKILL would otherwise leave solution.h5 unreadable (and with it
        # every earlier step); closed, only a kill during this write can damage it
        with compat.xdmf_file(self.comm, self.path, "a") as file:
            for f in (self.u1, self.v1, self.s1, self.a1):
                file.write_function(f, float(t))
