"""Post-processing of finished runs: reload their fields, recompute the energy, compare
solutions on non-matching meshes.

A run folder holds ``run.json`` (parameters), ``timeseries.csv`` (one row per step) and
``state.h5`` (the native dof vectors of U and V every ``--write-every`` steps, with the
dof coordinates). Everything here reads those files, never the running code's memory:

* :func:`rebuild` makes the run's Problem again from ``run.json`` (the command-line
  arguments it stores, or the problem's parameters for a run started with ``simulate``);
* :class:`StateReader` maps the stored dofs onto the rebuilt spaces by their coordinates,
  so a run written on k ranks is read on any number of ranks (HDF5 is read on rank 0 with
  h5py, Debian's h5py being serial, and scattered);
* :func:`recompute_energy` reassembles the discrete energy J^h of the paper's Theorem 2
  from the stored fields (``python -m sdm_dolfinx energy DIR``);
* :func:`evaluate_nonmatching` / :func:`interpolate_by_points` evaluate a function on
  another, non-matching mesh in parallel (each point is evaluated on the rank that owns a
  source cell containing it), which :func:`sdm_dolfinx.compat.interpolate_nonmatching`
  uses on dolfinx 0.5; :func:`h1_error` and :func:`convergence_rate` serve the disc's
  convergence study (paper Table 2, Fig. 16).
"""
import argparse
import csv
import inspect
import json
import sys
from pathlib import Path

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

from . import compat

#: the columns of energy_recomputed.csv
ENERGY_COLUMNS = ("step", "t", "energy", "kinetic", "potential")


class PostprocessError(RuntimeError):
    """A run folder cannot be post-processed (missing or inconsistent files)."""


# --------------------------------------------------------------------------- reading files
def _bcast_result(comm, func, *args):
    """Run ``func`` on rank 0 and broadcast its result (or its error) to every rank."""
    out, err = None, None
    if comm.rank == 0:
        try:
            out = func(*args)
        except (OSError, ValueError, KeyError) as e:
            err = f"{type(e).__name__}: {e}"
        except PostprocessError as e:
            err = str(e)
    err = comm.bcast(err, root=0)
    if err:
        raise PostprocessError(err)
    return comm.bcast(out, root=0)


def read_info(folder, comm=MPI.COMM_WORLD):
    """``folder/run.json`` as a dict, on every rank."""
    path = Path(folder) / "run.json"

    def read():
        if not path.exists():
            raise PostprocessError(f"{folder}: no run.json (not a run folder)")
        return json.loads(path.read_text())
    return _bcast_result(comm, read)


def read_timeseries(folder, comm=MPI.COMM_WORLD, name="timeseries.csv"):
    """``folder/timeseries.csv`` as {column: array}, on every rank."""
    path = Path(folder) / name

    def read():
        if not path.exists():
            raise PostprocessError(f"{folder}: no {name}")
        with open(path) as fh:
            rows = [r for r in csv.reader(fh) if r]
        header, rows = rows[0], rows[1:]
        rows = [r for r in rows if len(r) == len(header)]
        return {c: np.array([float(r[i]) for r in rows]) for i, c in enumerate(header)}
    return _bcast_result(comm, read)


# ------------------------------------------------------------------------ rebuilding runs
def _problem_module(name):
    from . import disc, membrane
    mods = {"membrane": membrane, "disc": disc}
    if name not in mods:
        raise PostprocessError(f"unknown problem {name!r} in run.json")
    return mods[name]


def rebuild_problem(info, comm=MPI.COMM_WORLD):
    """The run's Problem, made again on ``comm`` from ``run.json``'s contents.

    A run started from the command line stores its arguments (``cli_args``): they go
    through the problem module's ``problem_from_args`` exactly as in the run. A run started
    with :func:`sdm_dolfinx.simulate` has the problem's parameters only: they are passed
    to the problem factory (``membrane.Problem``, ``disc.Problem``).
    """
    name = info.get("command_name") or info["problem"]["name"]
    mod = _problem_module(name)
    if "cli_args" in info:
        ns = argparse.Namespace(**info["cli_args"])
        return mod.problem_from_args(ns, comm)
    params = dict(info["problem"]["parameters"])
    accepted = inspect.signature(mod.Problem).parameters
    kwargs = {k: v for k, v in params.items() if k in accepted and v is not None}
    if "probe" in accepted and "probe" in info["problem"]:
        kwargs["probe"] = tuple(info["problem"]["probe"])
    if name == "disc" and params.get("level") is not None:
        kwargs.pop("h", None)
    return mod.Problem(comm=comm, **kwargs)


def rebuild_spaces(problem, info):
    """(W, V-space) of the run: W^h, and the space of the stored V (W^h, or H^h for the
    consistent block variant)."""
    from .pairs import get_pair
    pair = get_pair(info["pair"])
    cell = compat.cell_name(problem.mesh)
    shape = tuple(problem.shape)
    W = compat.function_space(problem.mesh, pair.w_element(cell, shape))
    if info.get("mass") == "consistent":
        return W, compat.function_space(problem.mesh, pair.h_element(cell, shape))
    return W, W


def rebuild(folder, comm=MPI.COMM_WORLD):
    """(info, problem, W, V-space) of the run in ``folder``."""
    info = read_info(folder, comm)
    problem = rebuild_problem(info, comm)
    W, Vs = rebuild_spaces(problem, info)
    return info, problem, W, Vs


# ----------------------------------------------------------------------------- state.h5
def _owned_block_coordinates(V):
    n = V.dofmap.index_map.size_local
    return V.tabulate_dof_coordinates()[:n]


class StateReader:
    """Reads ``state.h5`` into Functions of the rebuilt spaces, on any number of ranks.

    The file stores vectors in the writing run's global numbering together with each dof's
    coordinates; here every owned dof block of the rebuilt space is matched to the stored
    block at the same point (k-d tree), which also checks that the meshes agree.

    Args:
        folder: the run folder.
        W, Vs: the rebuilt displacement and velocity spaces (:func:`rebuild_spaces`).
        comm: the spaces' communicator.
    """

    def __init__(self, folder, W, Vs, comm=MPI.COMM_WORLD):
        self.comm, self.path = comm, Path(folder) / "state.h5"

        def header():
            import h5py
            if not self.path.exists():
                raise PostprocessError(f"{folder}: no state.h5 (a run writes it when given an output folder)")
            with h5py.File(self.path, "r") as h5:
                return {"steps": h5["step"][:].astype(int), "t": h5["t"][:].astype(float),
                        "dtype": str(h5["U"].dtype),
                        "W": h5["W/dof_coordinates"][:], "bs_W": int(h5["W"].attrs["block_size"]),
                        "V": h5["V_space/dof_coordinates"][:], "bs_V": int(h5["V_space"].attrs["block_size"]),
                        "mesh": {k[5:]: v for k, v in h5.attrs.items() if k.startswith("mesh_")},
                        "V_is": str(h5.attrs.get("V_is", ""))}
        head = _bcast_result(comm, header)
        self.steps, self.t, self.dtype = head["steps"], head["t"], np.dtype(head["dtype"])
        self.V_is = head["V_is"]
        from .checkpoint import mesh_fingerprint, same_fingerprint
        if head["mesh"] and not same_fingerprint(head["mesh"], mesh_fingerprint(W.mesh), rtol=1e-10):
            raise PostprocessError(f"{folder}: the rebuilt mesh differs from the run's mesh "
                                   f"(state.h5 {head['mesh']}, rebuilt {mesh_fingerprint(W.mesh)})")
        self.W, self.Vs = W, Vs
        self._maps = {}
        for key, sp, coords, bs in (("U", W, head["W"], head["bs_W"]), ("V", Vs, head["V"], head["bs_V"])):
            if bs != sp.dofmap.index_map_bs:
                raise PostprocessError(f"{folder}: block size {bs} in state.h5, {sp.dofmap.index_map_bs} rebuilt")
            self._maps[key] = self._match(sp, coords, bs)

    def _match(self, V, coords, bs):
        """Per rank, the stored entry of each owned entry of V (gathered on rank 0)."""
        from scipy.spatial import cKDTree
        mine = _owned_block_coordinates(V)
        scale = max(float(np.ptp(coords, axis=0).max()), 1.0) if len(coords) else 1.0
        tree = cKDTree(coords)
        k = 2 if len(coords) > 1 else 1
        dist, idx = tree.query(mine, k=k)
        if k == 2:
            if len(mine) and dist[:, 1].min() <= 1e-9 * scale:
                raise PostprocessError("two stored dofs share one point: cannot match dofs by coordinates")
            dist, idx = dist[:, 0], idx[:, 0]
        bad = int(self.comm.allreduce(int(np.sum(dist > 1e-9 * scale)), op=MPI.SUM))
        if bad:
            raise PostprocessError(f"{bad} dofs of the rebuilt space have no stored dof at their point: "
                                   "the run's mesh or pair differs")
        entries = (idx[:, None] * bs + np.arange(bs)[None, :]).reshape(-1)
        n = self.comm.allreduce(len(entries), op=MPI.SUM)
        if n != len(coords) * bs:
            raise PostprocessError(f"the rebuilt space has {n} dofs, state.h5 {len(coords) * bs}")
        return self.comm.gather(entries, root=0)

    def __len__(self):
        return len(self.steps)

    def index_of_step(self, step):
        """Row of the stored step ``step`` (KeyError if that step was not written)."""
        hits = np.flatnonzero(self.steps == step)
        if not len(hits):
            raise KeyError(f"step {step} is not stored in {self.path}")
        return int(hits[-1])

    def _read_row(self, i):
        rows = None
        if self.comm.rank == 0:
            import h5py
            with h5py.File(self.path, "r") as h5:
                rows = (h5["U"][i].astype(float), h5["V"][i].astype(float))
        return rows

    def read(self, i, u=None, v=None):
        """Row ``i`` as Functions (u in W, v in the V space); pass Functions to fill them."""
        u = u if u is not None else fem.Function(self.W)
        v = v if v is not None else fem.Function(self.Vs)
        rows = self._read_row(i)
        for f, key, k in ((u, "U", 0), (v, "V", 1)):
            parts = [rows[k][m] for m in self._maps[key]] if self.comm.rank == 0 else None
            vals = self.comm.scatter(parts, root=0)
            f.x.array[:len(vals)] = vals
            f.x.scatter_forward()
        return u, v


# ---------------------------------------------------------------------------- energy
def _scalar(form, comm):
    return comm.allreduce(fem.assemble_scalar(compat.form(form)), op=MPI.SUM)


def recompute_energy(folder, comm=MPI.COMM_WORLD, write=True):
    """The energy J^h (paper Theorem 2) of every stored state, from ``state.h5`` alone.

    The potential ½ a(u, u) − l(u) is assembled from the run's UFL forms; the kinetic
    energy is ½ V̄ᵀ M V̄ with M = Bᵀ C⁻¹ B (or the standard mass) reassembled by a fresh
    :class:`~sdm_dolfinx.discretisation.Discretisation`, or ½ ∫ ρ v·v for a run that stored
    V in H^h (consistent block variant). Writes ``folder/energy_recomputed.csv`` (rank 0).

    Both energies are sums of many products that cancel (a rigid translation of the disc
    costs no elastic energy, yet every term of Uᵀ A U is large), so their difference is
    also measured against the round-off scale ½|U|ᵀ|A||U| + |U|ᵀ|L| + ½|V|ᵀ|M||V| (entrywise
    absolute values), which bounds what summation order can change.

    Returns:
        dict with the columns of :data:`ENERGY_COLUMNS` (arrays), ``max_rel_diff`` (the
        largest |J_recomputed − J_timeseries| over the stored steps, relative to the
        largest |J| of the time series), ``max_roundoff_ratio`` (the largest difference over
        that step's round-off scale: O(eps) when the two agree to round-off),
        ``stored_dtype`` and ``rows``.
    """
    from .discretisation import Discretisation
    info = read_info(folder, comm)
    problem = rebuild_problem(info, comm)
    disc = Discretisation(problem, info["pair"], info.get("mass"))
    Vs = disc.H if info.get("mass") == "consistent" else disc.W
    reader = StateReader(folder, disc.W, Vs, comm)
    u, v = fem.Function(disc.W), fem.Function(Vs)
    w = ufl.TestFunction(disc.W)
    # potential: 1/2 a(u, u) - l(u), the run's own UFL forms with u the stored field
    pot_form = compat.form(0.5 * problem.a(u, u) - ufl.action(problem.l(w), u))
    rho = fem.Constant(problem.mesh, float(problem.rho))
    kin_form = compat.form(0.5 * rho * ufl.inner(v, v) * ufl.dx) if Vs is not disc.W else None
    Mv = disc.M.createVecLeft() if kin_form is None else None
    cols = {c: np.zeros(len(reader)) for c in ENERGY_COLUMNS}
    absA = _abs_matrix(disc.A)
    absM = _abs_matrix(disc.M if kin_form is None else disc.C)
    absL = disc.L.copy()
    absL.abs()
    roundoff = np.zeros(len(reader))
    for i in range(len(reader)):
        reader.read(i, u, v)
        roundoff[i] = 0.5 * _abs_quadratic(absA, compat.petsc_vec(u)) + _abs_dot(absL, compat.petsc_vec(u)) \
            + 0.5 * _abs_quadratic(absM, compat.petsc_vec(v))
        pot = comm.allreduce(fem.assemble_scalar(pot_form), op=MPI.SUM)
        if kin_form is not None:
            kin = comm.allreduce(fem.assemble_scalar(kin_form), op=MPI.SUM)
        else:
            vv = compat.petsc_vec(v)
            disc.M.mult(vv, Mv)
            kin = 0.5 * vv.dot(Mv)
        cols["step"][i], cols["t"][i] = reader.steps[i], reader.t[i]
        cols["kinetic"][i], cols["potential"][i], cols["energy"][i] = kin, pot, kin + pot
    ts = read_timeseries(folder, comm)
    steps = ts["step"].astype(int)
    pos = {s: k for k, s in enumerate(steps)}
    rows = [k for k, s in enumerate(cols["step"].astype(int)) if s in pos]
    ref = np.array([ts["energy"][pos[int(cols["step"][k])]] for k in rows])
    scale = float(np.max(np.abs(ts["energy"]))) if len(ts["energy"]) else 1.0
    diff = np.abs(cols["energy"][rows] - ref)
    out = dict(cols, max_rel_diff=float(diff.max() / scale) if len(rows) else float("nan"),
               max_roundoff_ratio=float(np.max(diff / roundoff[rows])) if len(rows) else float("nan"),
               stored_dtype=str(reader.dtype), rows=len(rows))
    for m in (absA, absM):
        m.destroy()
    if write and comm.rank == 0:
        path = Path(folder) / "energy_recomputed.csv"
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "w") as fh:
            fh.write(",".join(ENERGY_COLUMNS) + "\n")
            for i in range(len(reader)):
                fh.write(",".join([str(int(cols["step"][i]))] + [repr(float(cols[c][i])) for c in ENERGY_COLUMNS[1:]])
                         + "\n")
        tmp.replace(path)
    comm.Barrier()
    return out


def _abs_matrix(A):
    """The matrix of entrywise absolute values |A| (same parallel layout)."""
    from petsc4py import PETSc
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
    ax = x.copy()
    ax.abs()
    return ax.dot(absb)


# --------------------------------------------------------------- non-matching meshes
def _owned_cells(msh):
    return np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)


def _owned_bbox(msh):
    """Bounding box (2, 3) of this rank's owned cells' geometry nodes (empty: +inf/-inf)."""
    cells = _owned_cells(msh)
    if not len(cells):
        return np.array([np.full(3, np.inf), np.full(3, -np.inf)])
    nodes = compat.mesh_geometry_dofmap(msh)[cells].reshape(-1)
    x = msh.geometry.x[nodes]
    return np.array([x.min(axis=0), x.max(axis=0)])


def _locate_local(msh, tree, points, padding):
    """For points (n, 3): an owned cell of this rank to evaluate each at, and the point's
    distance to it (0 inside; inf when no owned cell lies within ``padding``)."""
    n = len(points)
    cell = np.full(n, -1, dtype=np.int32)
    dist = np.full(n, np.inf)
    if not n:
        return cell, dist
    coll = compat.colliding_cells(msh, tree, points)
    offsets = coll.offsets
    has = np.diff(offsets) > 0
    cell[has] = coll.array[offsets[:-1][has]]
    dist[has] = 0.0
    missing = np.flatnonzero(~has)
    if len(missing):
        # outside every owned cell (e.g. beyond a curved boundary that the other mesh
        # approximates differently): the nearest owned cell within the padded boxes
        cand = compat.cell_candidates(tree, points[missing])
        from dolfinx import geometry
        for j, p in enumerate(missing):
            cs = cand.links(j)
            if not len(cs):
                continue
            d2 = geometry.squared_distance(msh, msh.topology.dim, cs, np.repeat(points[p:p + 1], len(cs), axis=0))
            k = int(np.argmin(d2))
            if np.sqrt(d2[k]) <= padding:
                cell[p], dist[p] = cs[k], float(np.sqrt(d2[k]))
    return cell, dist


def evaluate_nonmatching(u, points, padding=1e-8):
    """Values of ``u`` at ``points`` (n, 3) given on this rank, whatever the ranks that own
    the cells of ``u``'s mesh containing them (collective).

    Each point goes to the ranks whose owned cells' bounding box (padded) contains it; they
    locate it in an owned cell (bounding-box tree, exact collision) and evaluate there; of
    the answers the one from a containing cell (else the nearest cell within ``padding``,
    which extrapolates) wins, ties to the lowest rank.

    Args:
        u: a Function on a mesh over the same communicator.
        points: (n, 3) array.
        padding: how far outside the source mesh a point may lie (absolute length).

    Returns:
        (values (n, value_size), distance (n,)): distance 0 for points inside the source
        mesh, the distance to the cell used otherwise.

    Raises:
        PostprocessError: a point lies farther than ``padding`` from the source mesh.
    """
    msh = u.function_space.mesh
    comm = msh.comm
    points = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    u.x.scatter_forward()
    vs = int(np.prod(u.ufl_shape)) if u.ufl_shape else 1
    boxes = np.array(comm.allgather(_owned_bbox(msh)))            # (size, 2, 3)
    lo, hi = boxes[:, 0] - padding, boxes[:, 1] + padding
    inside = np.all((points[:, None, :] >= lo[None]) & (points[:, None, :] <= hi[None]), axis=2)  # (n, size)
    send_idx = [np.flatnonzero(inside[:, r]) for r in range(comm.size)]
    recv = comm.alltoall([points[i] for i in send_idx])
    tree = compat.cell_tree(msh, _owned_cells(msh), padding)
    answers = []
    for pts in recv:
        cell, dist = _locate_local(msh, tree, pts, padding)
        vals = np.zeros((len(pts), vs))
        ok = cell >= 0
        if ok.any():
            vals[ok] = u.eval(pts[ok], cell[ok]).reshape(-1, vs)
        answers.append((vals, dist))
    back = comm.alltoall(answers)
    values = np.zeros((len(points), vs))
    best = np.full(len(points), np.inf)
    for r in range(comm.size):            # ascending rank: ties go to the lowest rank
        vals, dist = back[r]
        idx = send_idx[r]
        better = dist < best[idx]
        values[idx[better]] = vals[better]
        best[idx[better]] = dist[better]
    lost = int(comm.allreduce(int(np.sum(~np.isfinite(best))), op=MPI.SUM))
    if lost:
        raise PostprocessError(f"{lost} points lie farther than {padding:g} from the source mesh")
    return values, best


def interpolate_by_points(u_to, u_from, padding=1e-8):
    """Interpolate ``u_from`` (any mesh) into ``u_to``'s space by evaluating it at the
    target element's interpolation points (exact for Lagrange-type elements; collective).

    This is the dolfinx 0.5 implementation behind
    :func:`sdm_dolfinx.compat.interpolate_nonmatching`; newer dolfinx has its own.
    """
    stats = {}

    def f(x):
        vals, dist = evaluate_nonmatching(u_from, x.T, padding)
        stats["max_distance"] = float(dist.max(initial=0.0))
        return vals.T if u_from.ufl_shape else vals[:, 0]
    u_to.interpolate(f)
    u_to.x.scatter_forward()
    return stats


# -------------------------------------------------------------------- norms and rates
def h1_norm(u, seminorm=False, l2_weight=1.0):
    """‖u‖_{H¹(Ω)} = (w ‖u‖²_{L²} + ‖∇u‖²_{L²})^½ (w = ``l2_weight``; 0 with ``seminorm``),
    reduced over ranks.

    The relative H¹ error depends on the length unit: lengths scaled by s (mm -> m:
    s = 1e-3) multiply the L² part by s² relative to the gradient part, so pass
    ``l2_weight = s**2`` for the norm in the other unit.
    """
    comm = u.function_space.mesh.comm
    expr = ufl.inner(ufl.grad(u), ufl.grad(u))
    if not seminorm:
        expr = expr + float(l2_weight) * ufl.inner(u, u)
    return float(np.sqrt(_scalar(expr * ufl.dx, comm)))


def h1_error(u, u_ref, seminorm=False, l2_weight=1.0):
    """Relative H¹ error ‖u − u_ref‖ / ‖u_ref‖ (both on u_ref's mesh; see :func:`h1_norm`)."""
    e = fem.Function(u_ref.function_space)
    e.x.array[:] = u.x.array - u_ref.x.array
    return h1_norm(e, seminorm, l2_weight) / h1_norm(u_ref, seminorm, l2_weight)


def convergence_rate(h, err):
    """Least-squares slope of log(err) against log(h) (the convergence order)."""
    h, err = np.asarray(h, dtype=float), np.asarray(err, dtype=float)
    if len(h) < 2 or np.any(h <= 0) or np.any(err <= 0):
        raise ValueError("a rate needs at least two positive (h, error) pairs")
    return float(np.polyfit(np.log(h), np.log(err), 1)[0])


# ---------------------------------------------------------------------- command line
def main(argv=None):
    """``python -m sdm_dolfinx energy DIR``: returns the exit status (0, 2 bad input)."""
    from .cli import UsageError, _Parser, parse_or_help, report_usage_error
    comm = MPI.COMM_WORLD
    argv = sys.argv[1:] if argv is None else list(argv)
    prog = "python -m sdm_dolfinx energy"
    parser = _Parser(prog=prog, description="Recompute the energy history of a run from its state.h5 "
                     "(independently of the run's own diagnostics), write DIR/energy_recomputed.csv and "
                     "print the largest relative difference to DIR/timeseries.csv.")
    parser.add_argument("folder", type=Path, metavar="DIR", help="a run's output folder")
    try:
        args = parse_or_help(parser, argv, comm)
        if args is None:
            return 0
        for name in ("run.json", "timeseries.csv", "state.h5"):
            if not (args.folder / name).exists():
                raise UsageError(f"{args.folder} has no {name} (not the output folder of a run)")
    except UsageError as e:
        return report_usage_error(prog, e, comm)
    try:
        res = recompute_energy(args.folder, comm)
    except PostprocessError as e:
        if comm.rank == 0:
            print(f"{prog}: error: {e}", file=sys.stderr, flush=True)
        return 2
    if comm.rank == 0:
        eps = np.finfo(np.dtype(res["stored_dtype"])).eps
        print(f"{args.folder}: energy of {len(res['step'])} stored states -> {args.folder}/energy_recomputed.csv; "
              f"max relative difference to timeseries.csv: {res['max_rel_diff']:.3e} "
              f"({res['max_roundoff_ratio'] / eps:.3g} eps of the round-off scale; {res['rows']} common steps; "
              f"state.h5 stores {res['stored_dtype']}, eps = {eps:.1e})", flush=True)
    return 0
