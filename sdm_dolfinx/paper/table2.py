"""Table 2 two ways: as the paper's program computed it, and at t = 0.02 s exactly.

The paper's program (GetFEM's ``contrib/mixed_dynamic_friction/mixed_dynamic_friction.cc``,
removed from GetFEM in 2015; read at commit 4fd4d557, with its ``.param`` and ``.m`` files):

* runs ``t = 0; while (t <= T) { step; t += dt; }`` in double precision
  (:func:`~sdm_dolfinx.paper.design.getfem_steps`): rows 1-4 end one step past T = 0.02 s
  (26, 51, 101, 201 steps: t = 0.0208, 0.0204, 0.0202, 0.0201 s), rows 5 and 6 exactly at
  0.02 s (400 and 800 steps);
* saves its last ``U0`` and, with ``COMPARE = 1``, interpolates it onto the mesh of the
  reference (the last ``U`` of another run of the same program, the finest row: 800 steps of
  2.5e-5 s, t = 0.02 s) and prints ``asm_H1_dist(U, Uref)`` and ``asm_H1_norm(Uref)``, the
  full H¹ norm (L² part plus gradient part): Table 2 is their ratio, at whatever times the two
  runs stopped;
* measures U from GetFEM's mesh, a disc centred at (0, 20) whose lowest point A touches the
  foundation y = 0, and starts from ``U0 = INIT_VERT_POS e_y = 10 e_y``: the disc starts 10 mm
  above the foundation;
* fits the rate 0.69 on rows 1-4 (``polyfit(log(H(2:5)), log(H1(2:5)), 1)`` against dt).

The displacement behind the denominator. Our mesh is the disc where it is at t = 0: GetFEM's
mesh moved up by the height h = 10 mm of A (for the paper's own meshes the reader,
``problems.disc_mesh.read_mesh``, makes exactly this translation). The material point at
GetFEM's X_g is at our X = X_g + h e_y, and both programs put it at x(t), so

    u_GetFEM(X_g, t) = x(t) - X_g = (x(t) - X) + (X - X_g) = u(X, t) + h e_y:

the translation between the two placements *is* U0 (counted once, not twice). Adding a constant to
both fields leaves the numerator unchanged (P2 interpolation reproduces constants); the
denominator becomes ‖u_ref + h e_y‖_{H¹}, whose L² part carries the rigid translation
(h √|Ω| = 10 √(400 π) ≈ 354 mm² alone) where ours, ‖u_ref‖_{H¹}, has only the motion since t = 0.
"""
import time

from dolfinx import fem

from sdm_dolfinx import io as sdm_io
from sdm_dolfinx import post
from sdm_dolfinx.paper.numbers import COMM, fit_rates
from sdm_dolfinx.paper.design import PAPER_MESHES, PAPER_T, PAPER_TABLE2, getfem_steps
from sdm_dolfinx.problems.disc_mesh import LEVELS
from sdm_dolfinx.run import num_steps

#: the printed values of rows 1-3 must be met within this relative tolerance on the paper's meshes
TOLERANCE = 0.03


def offset_norm(u, c, component=1, seminorm=False, l2_weight=1.0):
    """‖u + c e_component‖_{H¹} (see :func:`sdm_dolfinx.post.h1_norm`) for a Lagrange vector
    field ``u``: its nodal values shifted by ``c`` (exact: Lagrange elements reproduce
    constants). Collective."""
    w = fem.Function(u.function_space)
    bs = u.function_space.dofmap.index_map_bs
    w.x.array[:] = u.x.array
    w.x.array[component::bs] += c
    return post.h1_norm(w, seminorm, l2_weight)


def steps_of(run):
    """(step at t = 0.02 s, step the paper's program would stop at, the run's last step)."""
    dt = run.options["dt"]
    return num_steps(PAPER_T, dt), getfem_steps(PAPER_T, dt), run.steps


class _Reference:
    """The reference run's fields at its t = 0.02 step and at its paper-program step (collective)."""

    def __init__(self, run, folder, comm):
        self.run, self.folder = run, folder
        self.info, problem, self.W, Vs = post.rebuild(folder, comm)
        self.height = float(problem.parameters["height"])
        reader = sdm_io.StateReader(folder, self.W, Vs, comm)
        n02, npaper, _ = steps_of(run)
        self.u = {k: reader.read(reader.index_of_step(n))[0] for k, n in (("t002", n02), ("paper", npaper))}
        self.steps = {"t002": n02, "paper": npaper}
        self.norm = {"t002": post.h1_norm(self.u["t002"]),
                     "t002_paper_norm": offset_norm(self.u["t002"], self.height),
                     "paper": offset_norm(self.u["paper"], self.height)}
        self.semi = post.h1_norm(self.u["t002"], seminorm=True)
        self.metres = post.h1_norm(self.u["t002"], l2_weight=1e-6)


def _differences(ref, run, folder, padding, comm):
    """The coarse run's fields interpolated on the reference mesh, minus the reference's: H¹
    norms of the differences at t = 0.02 (norm, seminorm, lengths in m) and at the paper's steps."""
    info, _, W, Vs = post.rebuild(folder, comm)
    rd = sdm_io.StateReader(folder, W, Vs, comm)
    n02, npaper, last = steps_of(run)
    if int(rd.steps[-1]) != last or int(info["steps"]) != last:
        raise sdm_io.PostprocessError(f"{folder}: its last stored state is not its last step {last}")
    out = {}
    for key, n in (("t002", n02), ("paper", npaper)):
        u_c, _ = rd.read(rd.index_of_step(n))
        e = fem.Function(ref.W)
        post.interpolate_nonmatching(e, u_c, padding=padding)
        e.x.array[:] -= ref.u[key].x.array
        out[key] = post.h1_norm(e)
        if key == "t002":
            out["semi"], out["metres"] = post.h1_norm(e, seminorm=True), post.h1_norm(e, l2_weight=1e-6)
    return info, out


def family_errors(rows, ref, runs_dir, comm=COMM, say=print, label="", cache=None):
    """Table 2 for one mesh family: ``rows`` (Table 2 row -> Run) against the reference ``ref``
    (a :class:`_Reference`), both ways (collective). ``cache`` (run name -> row entry) shares
    the runs two families have in common."""
    cache = {} if cache is None else cache
    out = {}
    for row, run in sorted(rows.items()):
        if run.name not in cache:
            t0 = time.perf_counter()
            cache[run.name] = e = _row_entry(run, ref, runs_dir, comm)
            say(f"    {label}row {row} ({e['mesh']}): relative H1 error {100 * e['error_paper']:.3g} % as the "
                f"paper's program ({e['steps_paper']} steps), {100 * e['error_t002']:.3g} % at t = 0.02 "
                f"({time.perf_counter() - t0:.1f} s)")
        out[row] = cache[run.name]
    return {"rows": out, "reference": _reference_entry(ref), "rates": fit(out)}


def _row_entry(run, ref, runs_dir, comm):
    """One row: the run, its steps and its relative errors both ways."""
    row = run.params.get("level") or {f: r for r, f in PAPER_MESHES.items()}[mesh_label(run)]
    info, d = _differences(ref, run, runs_dir / run.name, 0.1 * LEVELS[row], comm)
    n02, npaper, _ = steps_of(run)
    return {"run": run.name, "mesh": mesh_label(run), "dofs": int(info["dim_W"]), "dt": run.options["dt"],
            "steps_t002": n02, "steps_paper": npaper, "t_paper": float(f"{npaper * run.options['dt']:.12g}"),
            "error_t002": d["t002"] / ref.norm["t002"], "seminorm_error_t002": d["semi"] / ref.semi,
            "metres_error_t002": d["metres"] / ref.metres,
            "error_t002_paper_norm": d["t002"] / ref.norm["t002_paper_norm"],
            "error_paper": d["paper"] / ref.norm["paper"], "wall_time": info.get("wall_time")}


def _reference_entry(ref):
    run = ref.run
    return {"run": run.name, "mesh": mesh_label(run), "dofs": int(ref.info["dim_W"]), "dt": run.options["dt"],
            "steps_t002": ref.steps["t002"], "steps_paper": ref.steps["paper"], "height_offset": ref.height,
            "norm_t002": ref.norm["t002"], "norm_t002_paper_norm": ref.norm["t002_paper_norm"],
            "norm_paper": ref.norm["paper"], "wall_time": ref.info.get("wall_time")}


def mesh_label(run):
    """``gmsh level 3`` or the paper's mesh file name."""
    mf = run.params.get("mesh_file")
    return f"gmsh level {run.params['level']}" if mf is None else str(mf).rsplit("/", 1)[-1]


def fit_rows(rows):
    """The rows the paper fitted its rate on: all but the one next to the reference (rows 1-4
    of 5: its ``.m`` file's ``H(2:5)``), when at least three remain; else all."""
    rows = sorted(rows)
    return rows[:-1] if len(rows) >= 4 else rows


def fit(rows):
    """Rates fitted against dt on :func:`fit_rows` (None with fewer than two rows)."""
    keys = fit_rows(rows)
    if len(keys) < 2:
        return {"fit_rows": keys, "paper": None, "t002": None}
    dt = [rows[r]["dt"] for r in keys]
    return {"fit_rows": keys, **{k: post.convergence_rate(dt, [rows[r][f"error_{k}"] for r in keys])
                                 for k in ("paper", "t002")}}


def table2_study(study, runs_dir, comm=COMM, say=print):
    """Both families (our gmsh levels; the paper's meshes on rows 1-4 with gmsh level 5 on row
    5, when the paper's meshes are there) against the finest gmsh level (collective):
    ``{"gmsh": family, "getfem": family or None, ...}`` (see :func:`family_errors`)."""
    levels = sorted(study.conv)
    ref_run = study.conv[levels[-1]]
    ref = _Reference(ref_run, runs_dir / ref_run.name, comm)
    coarse = {lev: study.conv[lev] for lev in levels[:-1]}
    cache = {}
    out = {"gmsh": family_errors(coarse, ref, runs_dir, comm, say, "gmsh ", cache), "getfem": None,
           "reference_level": levels[-1], "getfem_mesh_dir": str(study.getfem_mesh_dir or "")}
    if study.conv_getfem:
        rows = {**coarse, **study.conv_getfem}
        out["getfem"] = family_errors(rows, ref, runs_dir, comm, say, "paper's meshes ", cache)
    return out


def agreement(fam):
    """Rows 1-3 (those of the paper's meshes present) against the printed values: {row:
    relative deviation}, and whether all are within :data:`TOLERANCE`."""
    dev = {r: fam["rows"][r]["error_paper"] * 100 / PAPER_TABLE2[r][3] - 1 for r in (1, 2, 3) if r in fam["rows"]}
    return dev, bool(dev) and all(abs(d) <= TOLERANCE for d in dev.values())


def convergence(study, t2):
    """Fig. 16's numbers (:func:`sdm_dolfinx.paper.disc_figures.fig16`): our gmsh levels at
    t = 0.02 s in our norm, with the rates of :func:`sdm_dolfinx.paper.metrics.fit_rates`,
    plus the errors as the paper's program computed them (on its meshes where we have them)."""
    fam, ref = t2["gmsh"], t2["reference_level"]
    levels = sorted(study.conv)
    rows = fam["rows"]
    col = {k: {lev: rows[lev][k] for lev in rows} for k in ("error_t002", "seminorm_error_t002",
                                                           "metres_error_t002", "dofs", "wall_time")}
    dofs = {**col["dofs"], ref: fam["reference"]["dofs"]}
    rates = fit_rates(levels, ref, col["error_t002"], col["seminorm_error_t002"], dofs)
    rates["rate_metres"] = fit_rates(levels, ref, col["metres_error_t002"], col["seminorm_error_t002"], dofs)["rate"]
    program = t2["getfem"] or fam
    return {"levels": levels, "reference_level": ref, "errors": col["error_t002"],
            "seminorm_errors": col["seminorm_error_t002"], "errors_in_metres": col["metres_error_t002"],
            "dofs": dofs, **rates, "dt": {lev: study.conv[lev].options["dt"] for lev in levels},
            "wall_time": {**col["wall_time"], ref: fam["reference"]["wall_time"]},
            "paper_program_errors": {r: e["error_paper"] for r, e in program["rows"].items()},
            "paper_program_meshes": "the paper's meshes" if t2["getfem"] else "gmsh levels",
            "paper_program_rate": program["rates"]["paper"]}
