"""The metrics of the method comparison, the same for every method x problem x (h, dt).

Doyen, Ern, Piperno (SIAM J. Sci. Comput. 33 (2011) 223-249) compare dynamic-contact schemes on
1-D benchmarks by their energy, their penetration, the displacement, velocity and contact stress
at the contact point against the closed form, and the spurious oscillations of that stress; GetFEM's
``interface/tests/python/demo_dynamic_contact_1D.py`` adds the L^inf(0, T; L^2) and
L^inf(0, T; H^1) errors of the displacement field. Here:

* :class:`FieldErrors` is a ``simulate(..., observe=)`` callback: at every recorded state it measures
  ||U^n - I_h u(t_n)|| in L^2 and H^1 (the full norm, GetFEM's ``compute_H1_norm``) and the norms
  of I_h u(t_n) (I_h: interpolation in W^h, as the demo does with ``uExact`` at the dof nodes), and
  the penetration (the constrained vertices' gap and every boundary dof's);
* the functions below turn a run's time series (and those rows) into numbers, against an exact
  solution (``ExactSolution``: ``displacement(x, t)``, ``contact_stress(t)``, ``contact_intervals``)
  or against a reference run's series (the problems without a closed form).

Every function of time series is plain numpy (rank-local); only :class:`FieldErrors` is collective.
"""
import math
import time

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

from sdm_dolfinx import compat

#: a contact stress above this fraction of the largest exact (or reference) stress counts as contact
CONTACT_TOL = 1e-2
#: the oscillation index looks at each contact interval widened by this fraction of its length on
#: each side (the entering and leaving jumps belong to the contact phase)
WINDOW = 0.25
#: a reference whose RMS over [0, T] is below this fraction of its scale is zero (to round-off): a
#: relative error against it is not defined (it came out as 1e13 against a displacement of ~1e-16)
ZERO_REFERENCE = 1e-8
#: the metrics of the contact phases: not defined when the reference has no contact in [0, T]
CONTACT_PHASE = ("stress_contact_L2t", "oscillation_index", "release_time_error")


# ----------------------------------------------------------------------------- scalars of a series
def energy_errors(E):
    """(|E(T) - E(0)| / |E(0)|, max_t |E(t) - E(0)| / |E(0)|) of an energy history (contact energy
    included): the exact solution conserves the energy. inf for an empty or non-finite history."""
    E = np.asarray(E, dtype=float)
    if E.size == 0 or not np.all(np.isfinite(E)) or E[0] == 0:
        return math.inf, math.inf
    dev = np.abs(E - E[0]) / abs(E[0])
    return float(dev[-1]), float(dev.max())


def max_penetration(gaps):
    """max(0, -min gap): how far the constrained boundary went below its bound (0 if never)."""
    gaps = np.asarray(gaps, dtype=float)
    gaps = gaps[np.isfinite(gaps)]
    return float(max(0.0, -gaps.min())) if gaps.size else 0.0


def l2_time_error(t, values, exact):
    """Relative L^2(0, T) error sqrt(sum (v - e)^2 dt) / sqrt(sum e^2 dt) of sampled values against
    the exact samples (GetFEM's demo: rectangle rule on the run's grid; the absolute error when the
    exact samples vanish)."""
    t, v, e = (np.asarray(a, dtype=float) for a in (t, values, exact))
    w = np.full(t.size, float(np.mean(np.diff(t)))) if t.size > 1 else np.ones(t.size)
    num = math.sqrt(float(np.sum(w * (v - e) ** 2)))
    den = math.sqrt(float(np.sum(w * e ** 2)))
    return num / den if den > 0 else num


def linf_relative(errors, norms):
    """max_n ||e^n|| / max_n ||u(t_n)||: GetFEM's L^inf(0, T; X) relative error."""
    errors, norms = np.asarray(errors, dtype=float), np.asarray(norms, dtype=float)
    if errors.size == 0:
        return math.nan
    top = float(np.max(norms))
    return float(np.max(errors)) / top if top > 0 else float(np.max(errors))


def velocity_of(t, u):
    """The velocity at the contact point: the backward difference quotient of its displacement
    (the demo's definition at a contact node of its singular masses; the same for every method, so
    that Vbar's kernel component of a singular mass plays no part); v(0) = 0 (both benchmarks
    start at rest or the closed form says otherwise: the first entry is the second's)."""
    t, u = np.asarray(t, dtype=float), np.asarray(u, dtype=float)
    v = np.zeros_like(u)
    if u.size > 1:
        with np.errstate(divide="ignore", invalid="ignore"):     # a failed run's unwritten rows
            v[1:] = np.diff(u) / np.diff(t)
        v[0] = v[1]
    return v


def _windows(intervals, t_end, widen):
    """The contact intervals (t0, t1) that start before ``t_end``, widened by ``widen`` x their length
    on each side, cut half-way to their neighbours."""
    iv = sorted((float(a), float(b)) for a, b in intervals if a < t_end)
    out = []
    for k, (a, b) in enumerate(iv):
        w = widen * (b - a)
        lo = max(a - w, (iv[k - 1][1] + a) / 2 if k else -math.inf)
        hi = min(b + w, (b + iv[k + 1][0]) / 2 if k + 1 < len(iv) else math.inf)
        out.append((lo, hi, a, b))
    return out


def total_variation(values):
    """sum_n |v^{n+1} - v^n|."""
    return float(np.sum(np.abs(np.diff(np.asarray(values, dtype=float)))))


def oscillation_index(t, stress, exact_stress, intervals, widen=WINDOW):
    """Total variation of the contact stress over the contact phases divided by the exact stress's
    over the same samples (Doyen-Ern-Piperno's spurious oscillations in one number: 1 for a stress
    that rises and falls once as the exact one does, more for every spurious oscillation). Each
    phase is a contact interval widened by ``widen`` x its length (the jumps in and out count)."""
    t, s, e = (np.asarray(a, dtype=float) for a in (t, stress, exact_stress))
    num = den = 0.0
    for lo, hi, _, _ in _windows(intervals, t[-1] if t.size else 0.0, widen):
        k = (t >= lo) & (t <= hi)
        num += total_variation(s[k])
        den += total_variation(e[k])
    return num / den if den > 0 else math.nan


def release_times(t, stress, intervals, tol):
    """For each contact interval (t0, t1) that ends within the run: the numerical release time,
    the first sample after the last one of the phase (the interval widened by half its length, cut
    half-way to the neighbours) with a stress above ``tol``; nan when the stress never exceeds it."""
    t, s = np.asarray(t, dtype=float), np.asarray(stress, dtype=float)
    out = []
    for lo, hi, _, b in _windows(intervals, t[-1] if t.size else 0.0, 0.5):
        if b > t[-1]:
            continue
        k = np.flatnonzero((t >= lo) & (t <= hi) & (s > tol))
        out.append(float(t[min(k[-1] + 1, t.size - 1)]) if k.size else math.nan)
    return out


def release_time_error(t, stress, intervals, tol):
    """max over the contact intervals that end within the run of |numerical - exact release time|
    (nan without such an interval; inf when a phase has no contact at all)."""
    ends = [float(b) for a, b in sorted(intervals) if a < t[-1] and b <= t[-1]]
    rel = release_times(t, stress, intervals, tol)
    if not ends:
        return math.nan
    errs = [abs(r - b) if np.isfinite(r) else math.inf for r, b in zip(rel, ends)]
    return float(max(errs))


def contact_intervals_of(t, stress, tol):
    """The intervals (t0, t1) where a sampled stress exceeds ``tol`` (a reference run's contact
    phases): from the first sample above to the first below."""
    t, on = np.asarray(t, dtype=float), np.asarray(stress, dtype=float) > tol
    edges = np.flatnonzero(np.diff(on.astype(int)))
    out, start = [], (t[0] if on.size and on[0] else None)
    for k in edges:
        if on[k + 1]:
            start = t[k + 1]
        elif start is not None:
            out.append((float(start), float(t[k + 1])))
            start = None
    if start is not None:
        out.append((float(start), math.inf))
    return out


def cost_per_step(ts, info):
    """(mean Newton iterations per step, wall time per step in s: the run's wall time less its
    set-up and less the time its observer took (``observe_time``: the field errors), over its steps)."""
    its = np.asarray(ts.get("newton_its", []), dtype=float)[1:]
    steps = max(int(info.get("steps") or its.size), 1)
    wall = (info.get("wall_time") or math.nan) - (info.get("setup_time") or 0.0) - (info.get("observe_time") or 0.0)
    return (float(its.mean()) if its.size else math.nan), float(wall / steps)


def series_metrics(ts, info, truth, rows=None):
    """Every metric of one run.

    Args:
        ts: the time series (column -> array; ``t``, ``energy``, ``u_probe``, ``lambda_probe``,
            ``newton_its``; ``gap_min_boundary`` when present).
        info: run.json's content (``steps``, ``wall_time``, ``setup_time``, ``dim_W``).
        truth: the exact or reference values at the contact point: a dict with ``u(t)``, ``s(t)``
            (callables on arrays of times) and ``intervals`` (the contact intervals).
        rows: :meth:`FieldErrors.table` (None: no field errors, no observed gap).
    Returns:
        dict of floats (see :data:`METRICS`), and ``undefined``: metric -> why it is not defined (its
        value nan: :func:`undefined_metrics`).
    """
    t = np.asarray(ts["t"], dtype=float)
    eT, emax = energy_errors(ts["energy"])
    u_ex, s_ex = np.asarray(truth["u"](t), dtype=float), np.asarray(truth["s"](t), dtype=float)
    tol = CONTACT_TOL * max(float(np.max(np.abs(s_ex), initial=0.0)), 1e-300)
    gaps = list(np.asarray(ts.get("gap_min_boundary", []), dtype=float)[1:])
    out = {"energy_error_T": eT, "energy_error_max": emax,
           "u_contact_L2t": l2_time_error(t, ts["u_probe"], u_ex),
           "v_contact_L2t": l2_time_error(t, velocity_of(t, ts["u_probe"]), velocity_of(t, u_ex)),
           "stress_contact_L2t": l2_time_error(t, ts["lambda_probe"], s_ex),
           "oscillation_index": oscillation_index(t, ts["lambda_probe"], s_ex, truth["intervals"]),
           "release_time_error": release_time_error(t, ts["lambda_probe"], truth["intervals"], tol)}
    if rows is not None and len(rows["t"]):
        gaps += list(rows["gap"][1:])
        out["u_LinfL2"] = linf_relative(rows["err_L2"], rows["norm_L2"])
        out["u_LinfH1"] = linf_relative(rows["err_H1"], rows["norm_H1"])
    out["penetration_max"] = max_penetration(gaps)
    out["newton_per_step"], out["wall_per_step"] = cost_per_step(ts, info)
    out["undefined"] = undefined_metrics(t, u_ex, s_ex, truth)
    out.update({k: math.nan for k in out["undefined"]})
    return out


def undefined_metrics(t, u_ex, s_ex, truth):
    """metric -> the reason it is not defined for these reference values: the contact-phase metrics
    when the reference has no contact in [0, T]; a relative error whose reference at the contact
    point is zero, or zero to round-off against the reference's own scale (``truth["u_scale"]``:
    the reference field's max_n ||u(t_n)||_L2 / sqrt(|Omega|), a displacement; u_scale / T for a
    velocity), never against the run it judges."""
    what = truth.get("what", "the reference")
    T = float(t[-1]) if len(t) else 0.0
    out = {}
    if not any(a < T for a, _ in truth["intervals"]):
        out.update({k: f"no contact in [0, {T:g}] ({what})" for k in CONTACT_PHASE})
    scale = truth.get("u_scale")
    scale = float(scale) if scale is not None and np.isfinite(scale) and scale > 0 else None
    refs = {"u_contact_L2t": ("displacement", u_ex, scale), "stress_contact_L2t": ("contact stress", s_ex, None),
            "v_contact_L2t": ("velocity", velocity_of(t, u_ex), scale / T if scale and T > 0 else None)}
    for k, (name, ref, s) in refs.items():
        rms = math.sqrt(float(np.mean(np.asarray(ref, dtype=float) ** 2))) if len(ref) else 0.0
        if k in out:
            continue
        if rms == 0.0:
            out[k] = f"{what}'s {name} at the contact point is zero on [0, {T:g}]"
        elif s is not None and rms <= ZERO_REFERENCE * s:
            out[k] = (f"{what}'s {name} at the contact point is zero to round-off (RMS {rms:.2g} against its "
                      f"scale {s:.2g})")
    return out


#: the metrics, their meaning and whether smaller is better (all are)
METRICS = {
    "energy_error_T": "|E(T) - E(0)| / E(0) (contact energy included)",
    "energy_error_max": "max_t |E(t) - E(0)| / E(0)",
    "penetration_max": "max over the run of the constrained boundary's depth below its bound",
    "u_contact_L2t": "relative L2(0,T) error of the displacement at the contact point",
    "v_contact_L2t": "relative L2(0,T) error of the velocity at the contact point (difference quotient)",
    "stress_contact_L2t": "relative L2(0,T) error of the contact stress at the contact point",
    "u_LinfL2": "relative Linf(0,T; L2) error of the displacement field (GetFEM's demo)",
    "u_LinfH1": "relative Linf(0,T; H1) error of the displacement field (GetFEM's demo)",
    "oscillation_index": "total variation of the contact stress over the contact phases / the exact one's",
    "release_time_error": "max |numerical - exact release time| over the contact phases",
    "newton_per_step": "mean Newton iterations per step",
    "wall_per_step": "wall time per step (s), set-up excluded",
}


def exact_truth(exact, probe, T=None):
    """The exact solution's values at the contact point ``probe`` (its contact intervals up to T,
    default its horizon) as :func:`series_metrics` wants them."""
    x = np.zeros((3, 1))
    x[:len(probe), 0] = probe

    def u(t):
        return np.array([_scalar(exact.displacement(x, float(s))) for s in np.atleast_1d(t)])

    def s(t):
        return np.array([float(exact.contact_stress(float(r))) for r in np.atleast_1d(t)])

    intervals = exact.intervals(T) if T is not None else exact.contact_intervals
    return {"u": u, "s": s, "intervals": list(intervals), "what": "the exact solution"}


def reference_truth(ts_ref):
    """A reference run's series as :func:`series_metrics` wants them (linear interpolation in time;
    its contact phases where its stress exceeds :data:`CONTACT_TOL` x its largest)."""
    tr, ur, sr = (np.asarray(ts_ref[k], dtype=float) for k in ("t", "u_probe", "lambda_probe"))
    tol = CONTACT_TOL * max(float(np.max(np.abs(sr), initial=0.0)), 1e-300)
    return {"u": lambda t: np.interp(t, tr, ur), "s": lambda t: np.interp(t, tr, sr),
            "intervals": contact_intervals_of(tr, sr, tol), "what": "the reference run"}


def domain_measure(mesh, comm):
    """|Omega|, reduced over the ranks."""
    one = fem.Constant(mesh, 1.0)
    return comm.allreduce(float(fem.assemble_scalar(compat.form(one * ufl.dx(domain=mesh)))), op=MPI.SUM)


def _scalar(v):
    """The constrained component of one point's value (a scalar, or the first entry)."""
    return float(np.asarray(v, dtype=float).reshape(-1)[0])


# ----------------------------------------------------------------------------- field errors (observe)
class FieldErrors:
    """``observe(state)`` for :func:`~sdm_dolfinx.run.simulate` (``state``: a read-only
    :class:`~sdm_dolfinx.run.observe.State`): per recorded state the L^2 and H^1 norms of
    U^n - I u(t_n) and of I u(t_n), and the gap (collective; every rank holds the rows).

    Args:
        exact: an ExactSolution (``displacement(x, t)``: x of shape (3, n) -> (n,) for a scalar
            field, (gdim, n) or (n,) (the constrained component, the others 0) for a vector one),
            or None (then only the gap is recorded).
        raise_degree: I interpolates into Lagrange of W^h's degree plus this on the same mesh: 0 is
            GetFEM's demo (the interpolant in W^h, the default, so that our numbers are its numbers);
            k > 0 measures the error against a better approximation of u itself.
    """

    COLUMNS = ("t", "err_L2", "err_H1", "norm_L2", "norm_H1", "gap")
    #: it changes nothing of the run (the run need not watch its forms: sdm_dolfinx.method.frozen)
    read_only = True

    def __init__(self, exact=None, raise_degree=0):
        self.exact, self.raise_degree = exact, int(raise_degree)
        self.rows, self._forms = [], None
        self.seconds = 0.0          # the time spent here (not the method's cost)

    def _setup(self, d):
        self.comm, self.uh = d.comm, fem.Function(d.W)
        self.component = d.problem.constraint_component or 0
        space = d.W
        if self.raise_degree:
            deg = compat.element_degree(d.W) + self.raise_degree
            space = compat.function_space(d.problem.mesh, compat.element("Lagrange", compat.cell_name(
                d.problem.mesh), deg, tuple(d.problem.shape)))
        self.ue, self.e, self.ui = fem.Function(space), fem.Function(space), fem.Function(space)
        self.bs = space.dofmap.index_map_bs

        def sq(f):
            return (compat.form(ufl.inner(f, f) * ufl.dx), compat.form(ufl.inner(ufl.grad(f), ufl.grad(f)) * ufl.dx))
        self._forms = (sq(self.e), sq(self.ue))
        self.measure = domain_measure(d.problem.mesh, self.comm)

    def displacement_scale(self):
        """The exact field's max_n ||u(t_n)||_L2 / sqrt(|Omega|), a displacement (None without rows)."""
        norms = [r[3] for r in self.rows if np.isfinite(r[3])]
        return max(norms) / math.sqrt(self.measure) if norms and getattr(self, "measure", 0) > 0 else None

    def _exact_values(self, x, t):
        v = np.asarray(self.exact.displacement(x, t), dtype=float)
        if self.bs == 1 or (v.ndim == 2 and v.shape[0] == self.bs):
            return v.reshape(self.bs, -1) if self.bs > 1 else v.reshape(-1)
        out = np.zeros((self.bs, x.shape[1]))
        out[self.component] = v.reshape(-1)
        return out

    def __call__(self, state):
        t0 = time.perf_counter()
        try:
            self._record(state)
        finally:
            self.seconds += time.perf_counter() - t0

    def _record(self, state):
        t, U = state.t, state.U
        if self._forms is None:
            self._setup(state.discretisation)
        gap = min(state.vertex_gap(), state.boundary_gap())
        if self.exact is None:
            self.rows.append((t, math.nan, math.nan, math.nan, math.nan, gap))
            return
        self.uh.x.array[:len(U)] = U
        self.uh.x.scatter_forward()
        self.ue.interpolate(lambda x: self._exact_values(x, t))
        if self.raise_degree:
            self.ui.interpolate(self.uh)
        else:
            self.ui.x.array[:] = self.uh.x.array
        self.e.x.array[:] = self.ui.x.array - self.ue.x.array
        vals = [self.comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM) for pair in self._forms for f in pair]
        eL2, eH1s, uL2, uH1s = (max(float(v), 0.0) for v in vals)
        self.rows.append((t, math.sqrt(eL2), math.sqrt(eL2 + eH1s), math.sqrt(uL2), math.sqrt(uL2 + uH1s), gap))

    def table(self):
        """The rows as column -> array (:data:`COLUMNS`)."""
        a = np.array(self.rows, dtype=float).reshape(-1, len(self.COLUMNS))
        return {c: a[:, k] for k, c in enumerate(self.COLUMNS)}

    def csv_text(self):
        """The rows as CSV text (a header line, then one line per recorded state)."""
        lines = [",".join(self.COLUMNS)] + [",".join(f"{v:.17g}" for v in r) for r in self.rows]
        return "\n".join(lines) + "\n"
