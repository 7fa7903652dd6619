"""The frictional step solver: Signorini contact with Tresca or Coulomb friction (2-D; 3-D in
:mod:`~sdm_dolfinx.solvers.friction_cone`, a subclass), by the
primal-dual active set method with stick and slip sets of S. Hüeber, G. Stadler,
B. Wohlmuth, SIAM J. Sci. Comput. 30 (2008) 572–596 (HSW), i.e. the semi-smooth Newton
method on the complementarity functions of P. Alart, A. Curnier (1991).

At each contact vertex i there is a normal dof n_i (along the contact normal, the dof the
frictionless solver constrains) and one tangential dof t_i (2-D: friction is a box
constraint per vertex; 3-D, a disc: :mod:`~sdm_dolfinx.solvers.friction_cone`). Sign convention: r = K x - b is
the reaction the obstacle applies to the body (K x = b + r), zero off the contact dofs;
lam_N = r_n (>= 0 when the obstacle pushes), lam_T = r_t, and d = x_t - xref_t is the slip
of the step (xref: the previous step's constrained iterate, given by the caller). Then

    x_n >= lb,   lam_N >= 0,   lam_N (x_n - lb) = 0                      (Signorini)
    |lam_T| <= g,   |lam_T| < g  =>  d = 0,   d != 0  =>  lam_T = -g sign(d)   (friction)

with g = s (Tresca, given thresholds) or g = mu lam_N (Coulomb): the friction force opposes
the slip (a vertex dragged towards +t slips with d > 0 and is held back by lam_T = -g).
Tresca friction acts at every contact vertex, in contact or not (the classical Tresca
problem, a convex minimisation); a variant with friction only where the vertex is in
contact has a threshold discontinuous in the contact status, and its active set method
cycled in the measurements: Coulomb (g = 0 off contact) is the law for a body that leaves
the obstacle.

Alart–Curnier's functions in this convention (HSW's (2.10)-(2.11) write the multiplier with
the opposite sign, whence their "+ c_t d"):

    lam_N = max(0, lam_N - c_n (x_n - lb)),
    lam_T = proj_[-g, g](lam_T - c_t d),    g = s  or  mu max(0, lam_N - c_n (x_n - lb)).

Each Newton iteration takes the sets these functions select at the current iterate
(:meth:`FrictionalNewton._predict`: active, stick, slip with its direction sigma) and
solves K x - b = r with x_n = lb on the active set, lam_N = 0 off it, x_t = xref on the
stick set, lam_T = sigma g on the slip set (for Coulomb sigma mu lam_N: linear in the
unknown lam_N) and lam_T = 0 at vertices without friction. K is factorised once per run
and each system is a small dense one on cached columns of K^-1
(:mod:`~sdm_dolfinx.solvers.friction_system`): non-symmetric for Coulomb, solved by LU
(LAPACK), which needs no symmetry and costs little at these sizes. The iterations stop when
no condition is violated by more than the tolerance (rtol max|b| for forces, divided by the
mean diagonal of K for displacements): stick vertices then have d = 0 and slipping ones
lam_T = -g sign(d) to round-off.

Coulomb is solved by that Newton method on the coupled problem (``coulomb="newton"``), as
a fixed point on Tresca problems with thresholds s = mu lam_N of the previous one
(``"fixed-point"``), or by Newton and, if it fails, the fixed point (``"auto"``, the
default). Measured (``bench/friction_solver.py --study iterations``: an elastic block on a
bowl, 33 or 65 contact vertices, pressed, lifted off and dragged back and forth over 24
steps, mu = 0.05 ... 10): Newton 2.9-4.7 iterations per step on average, at most 12, no
failure for mu <= 2, one failed step in 24 in 4 of the 6 runs with mu = 5 or 10; the fixed
point 6-19 on average, at most 45 for mu <= 2 (188 at mu = 5), and it also failed at
mu >= 5; ``auto`` failed only at mu = 10 (one step in 24, in 2 runs of 3). Tresca: 2.8-5.6
on average, at most 14 but 188 once (Murty's rule, see :meth:`FrictionalNewton._newton`).
Cost per step (``--study cost``, 50k dofs, 201 contact vertices, 1 rank): with a
mass-dominated K (a2 = 100, as the method's step matrices) Coulomb Newton 5.1-5.7 ms
against 5.5 ms for the frictionless SemismoothNewton, Tresca 12 ms (every tangential dof is
then in the dense system); with a2 = 0.01 (~200 vertices in contact) Coulomb Newton 53-65
ms, the fixed point 162 ms, the frictionless ``schur`` 71 ms once its dense Schur
complement is allowed beyond 100 active constraints (1.9 s with its CG fallback). The
first step adds the cached columns: ~1.9 s for 402 columns.
"""
from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from sdm_dolfinx.solvers.base import MurtyRule, VIError
from sdm_dolfinx.solvers.factorisation import Factorisation
from sdm_dolfinx.solvers.friction_frames import NodeFrames
from sdm_dolfinx.solvers.friction_rows import RowColumns, RowSystem
from sdm_dolfinx.solvers.friction_system import FrictionSystem
from sdm_dolfinx.solvers.options import instance_prefix, scoped_options, vi_tolerances

#: friction laws and the ways to solve Coulomb
LAWS = ("tresca", "coulomb")
COULOMB_METHODS = ("auto", "newton", "fixed-point")
#: ``auto`` gives Newton this many iterations before the fixed point: it took at most 12 in
#: the measurements when it converged, and more iterations never ended its cycles (mu >= 5)
AUTO_NEWTON_MAX_IT = 30


def _coefficients(law, mu, threshold, m):
    """(mu, s) per vertex for the law, checked (ValueError with a one-line reason)."""
    if law not in LAWS:
        raise ValueError(f"unknown friction law {law!r}; choose one of {', '.join(LAWS)}")
    name, value = ("mu", mu) if law == "coulomb" else ("threshold", threshold)
    if value is None:
        raise ValueError(f"{law} friction needs {name}")
    v = np.broadcast_to(np.asarray(value, dtype=float), (m,)).copy()
    if not np.all(np.isfinite(v) & (v >= 0.0)):
        raise ValueError(f"{name} must be finite and >= 0")
    return (v, None) if law == "coulomb" else (None, v)


class FrictionalNewton(NodeFrames):
    """Primal-dual active set (semi-smooth Newton) solver of the frictional step problem.

    Args:
        K: the step matrix (PETSc Mat, Dirichlet rows = identity rows).
        ndofs, tdofs: owned local indices of the normal and tangential dofs of this rank's
            contact vertices (pairs: both dofs of a vertex on the same rank).
        lb: the lower bounds of the normal dofs.
        law: ``"tresca"`` (needs ``threshold``) or ``"coulomb"`` (needs ``mu``); a scalar
            or one value per vertex, >= 0.
        coulomb: ``"auto"`` (Newton, then the fixed point if it fails), ``"newton"`` on the
            coupled problem or ``"fixed-point"`` on Tresca thresholds (see the module).
        c_t: the tangential Alart–Curnier parameter of the set update (see :meth:`_predict`);
            0 (default): the limit c_t -> 0+, measured the most robust.
        symmetric_positive: K is SPD (Cholesky) or only symmetric (LDL^T / LU).
        prefix, options: PETSc options prefix and defaults of this instance, as for
            :class:`~sdm_dolfinx.solvers.semismooth.SemismoothNewton` (``vi_rtol``,
            ``vi_max_it``, ``vi_monitor``, the factorisation's ``factor_*``).
        factor_matrix: optional sparser augmented matrix factorised instead of K.
        rtol: tolerance of the complementarity tests, relative to max|b|.
        max_it: Newton iterations per step (and Tresca solves of the fixed point); 500 as
            for the frictionless solver (Murty's rule took 188 on a block pulled off the
            plane under Tresca friction).
        rows: ``(R, offset)`` of :func:`~sdm_dolfinx.solvers.friction_rows.rows_matrix`: the normal and
            tangential "dofs" are this rank's rows of R (the weighted gap), ``lb`` their bounds;
            ``ndofs`` and ``tdofs`` name the rows' vertices (their own dofs).
        surface: the global dofs (sorted) rows between bodies may read: the conditions are on rows given
            anew before every step by :meth:`set_rows` ``((ids, values), lb)``
            (:meth:`~sdm_dolfinx.method.body_rows.BodyRows.rows` with its tangential rows); ``ndofs`` and
            ``tdofs`` name the rows' slave vertices.
        frames: the obstacle's normal turns from node to node and step to step (a curved or
            tilted obstacle): ``ndofs`` and ``tdofs`` are then each node's Cartesian dofs
            (components 0, then 1 (and 2)), and :meth:`set_rows` gives the normals and bounds
            before every step; the normal and tangential "dofs" are the components in the node's
            frame (:meth:`~sdm_dolfinx.solvers.friction_system.FrictionSystem.set_frames`).

    After :meth:`solve`: ``lam`` (normal reactions), ``lam_t`` (tangential ones),
    ``active``, ``stick``, ``slip`` (bool per vertex; a vertex without friction is neither
    stick nor slip), ``total_linear_its`` (solves with the factorisation).
    """

    def __init__(self, K, ndofs, tdofs, lb, law="tresca", mu=None, threshold=None, coulomb="auto",
                 c_t=0.0, symmetric_positive=True, prefix=None, options=None,
                 factor_matrix=None, rtol=1e-10, max_it=500, frames=False, rows=None, surface=None):
        self.K, self.comm = K, K.getComm().tompi4py()
        self.frames = bool(frames)
        #: the conditions are on rows of a matrix (the weighted gap: :mod:`.friction_rows`)
        self.rowwise = rows is not None
        self.ndofs = np.asarray(ndofs, dtype=np.int32)
        self.tdofs = np.asarray(tdofs, dtype=np.int32)
        self.lb = np.asarray(lb, dtype=float)
        self.m = m = len(self.ndofs)
        if len(self.tdofs) != m or len(self.lb) != m:
            raise ValueError(f"ndofs, tdofs and lb differ in length ({m}, {len(self.tdofs)}, {len(self.lb)})")
        if coulomb not in COULOMB_METHODS:
            raise ValueError(f"unknown Coulomb method {coulomb!r}; choose one of {', '.join(COULOMB_METHODS)}")
        if not c_t >= 0.0:
            raise ValueError(f"c_t must be >= 0, not {c_t!r}")
        self.law, self.coulomb, self.c_t = law, coulomb, float(c_t)
        self.mu, self.s = _coefficients(law, mu, threshold, m)
        self._s_all = self.s
        self.prefix, self.options = instance_prefix(self.comm, prefix), dict(options or {})
        with scoped_options(self.prefix, self.options, inherit=True) as scope:
            self.rtol, self.max_it, self.monitor = vi_tolerances(scope, rtol, max_it)
            self.fac = Factorisation(K, symmetric_positive, self.prefix + "factor_", aug=factor_matrix)
        # the contact dofs: normal, then each tangential component (3-D: tdofs is m x 2)
        #: the rows change every step (contact between bodies: :meth:`set_rows` gives them)
        self.surface = surface is not None
        self.rowwise = self.rowwise or self.surface
        if self.rowwise:
            k = 1 + (self.tdofs.shape[1] if self.tdofs.ndim == 2 else 1)
            R, offset = rows if rows is not None else (None, self.comm.exscan(k * m) or 0)
            self.system = RowSystem(K, R, offset, k * m, self.fac, read=surface)
            #: what a restart replays of the cached columns (``run.solver_state``: by dof)
            self.rows = RowColumns(self.system)
        else:
            self.system = FrictionSystem(K, np.concatenate([self.ndofs, self.tdofs.T.reshape(-1)]), self.fac)
        diag = K.getDiagonal()
        self.c_n, self.k_t = (self._mean(diag.array_r[dofs]) for dofs in (self.ndofs, self.tdofs))
        if self.frames or self.rowwise:     # the frame's axes (rows) mix the components: one scale for all
            self.c_n = self.k_t = self._mean(diag.array_r[self.system.cdofs])
        diag.destroy()
        self.lam, self.lam_t = np.zeros(m), np.zeros(self.tdofs.shape)
        self.active, self.stick, self.slip = (np.zeros(m, dtype=bool) for _ in range(3))
        self._sets = None               # (active, stick, sigma) to start the next solve from

    def _mean(self, values):
        total = self.comm.allreduce(float(np.sum(values)), op=MPI.SUM)
        n = self.comm.allreduce(int(np.size(values)), op=MPI.SUM)
        return total / n if n else 1.0

    @property
    def total_linear_its(self):
        """Solves with the factorisation so far (one per step, one per cached column)."""
        return self.system.its

    @property
    def column_ids(self):
        """Global ids of the contact dofs whose columns K^-1 e_j the solver caches: entry k is
        component k // m (0 normal, then the tangential ones) of vertex k % m (the order of ``ndofs``)."""
        return self.system.gc

    def cache_columns(self, gids):
        """Solve and cache the columns K^-1 e_g of ``gids`` not cached yet, as a step does
        (collective, the same list on every rank). A column's last bits depend on the batch it
        was solved in (one multiple-right-hand-side solve), so a restart replays a run's batches
        in their order."""
        self.system.cols.ensure(np.asarray(gids, dtype=np.int64))

    #: the per-vertex entries of :meth:`state`
    STATE = ("next_active", "next_stick", "next_sigma", "lam", "lam_t", "active", "stick", "slip")

    def state(self):
        """What the next step depends on besides x and b, for a checkpoint: (started, starts,
        per_vertex). ``started``: a step has been solved (else the first step derives its sets
        from x); ``starts``: solves of right-hand sides so far (the counter of
        :attr:`total_linear_its` besides the cached columns); ``per_vertex``: :data:`STATE` ->
        this rank's values (m rows, in the order of ``ndofs``, as floats): the sets and slip
        directions the next step starts from (3-D: z, see :mod:`.friction_cone`), the last
        multipliers (the 3-D linearisation and the Coulomb fixed point start from them) and the
        last step's sets."""
        started = self._sets is not None
        m = self.m
        sets = self._sets if started else (np.zeros(m, dtype=bool), np.zeros(m, dtype=bool), self._initial_sigma())
        values = (*sets, self.lam, self.lam_t, self.active, self.stick, self.slip)
        return started, self.system.starts, {k: np.asarray(v, dtype=float).reshape(m, int(np.prod(np.shape(v)[1:])))
                                             for k, v in zip(self.STATE, values)}

    def set_state(self, started, starts, per_vertex):
        """Restore a :meth:`state` (this rank's rows, in the order of ``ndofs``)."""
        v = {k: np.asarray(per_vertex[k], dtype=float) for k in self.STATE}
        flag = {k: v[k].reshape(self.m).astype(bool) for k in ("next_active", "next_stick", "active", "stick", "slip")}
        sigma = v["next_sigma"].reshape(self._initial_sigma().shape)
        self._sets = (flag["next_active"], flag["next_stick"], sigma) if started else None
        self.lam, self.lam_t = v["lam"].reshape(self.m), v["lam_t"].reshape(self.tdofs.shape)
        self.active, self.stick, self.slip = flag["active"], flag["stick"], flag["slip"]
        self.system.starts = int(starts)

    def solve(self, b, x, xref_t):
        """Solve the step for right-hand side b; x holds the initial guess and the result.

        Args:
            xref_t: the reference values of the tangential dofs (this rank's, in the order
                of ``tdofs``): the slip of the step is x_t - xref_t.

        Returns:
            dict with ``its`` (Newton iterations, summed over the Tresca solves of the fixed
            point, whose number is ``outer``), ``n_active``, ``n_stick``, ``n_slip``.

        Raises:
            VIError: no convergence, or a singular Newton system.
        """
        xref = np.asarray(xref_t, dtype=float)
        if xref.shape != self.tdofs.shape:
            raise ValueError(f"xref_t has shape {xref.shape}; expected {self.tdofs.shape}")
        tol = self.rtol * max(b.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        self.system.start(b)
        if self._sets is None:          # the first step: contact where x penetrates, stick where friction
            active = self._components(x.array_r)[0] < self.lb
            stick = active if self.s is None else self.s > 0.0
            self._sets = (active, stick, self._initial_sigma())
        info = self._step(xref, tol)
        self.system.finish(b, x)
        self._impose(x.array, xref)
        counts = (np.count_nonzero(v) for v in (self.active, self.stick, self.slip))
        n = self.comm.allreduce(np.array(list(counts)), op=MPI.SUM)
        return {**info, "n_active": int(n[0]), "n_stick": int(n[1]), "n_slip": int(n[2])}

    def _impose(self, xa, xref):
        """The converged conditions exactly (not to round-off) in the owned array xa: x_n = lb on the
        active set, x_t = xref on the stick set (frames: in the node's frame, rotated back; rows: nothing,
        a row's value combines several dofs)."""
        if self.rowwise:
            return
        if not self.frames:
            xa[self.ndofs[self.active]] = self.lb[self.active]
            xa[self.tdofs[self.stick]] = xref[self.stick]
        else:
            self.system.impose(xa, self.active, self.lb, self.stick, xref)

    def _initial_sigma(self):
        """The slip directions before the first step (2-D: +1 per vertex)."""
        return np.ones(self.m)

    def _predict(self, xn, lamN, lamT, d, sets, s):
        """The sets the complementarity functions select at an iterate (the semi-smooth
        Newton step): (active, stick, sigma); s: Tresca thresholds, None: Coulomb.

        active: lam_N - c_n (x_n - lb) > 0 (the rule of the frictionless solver). c_t > 0:
        HSW's rule, z = lam_T - c_t d, stick where |z| <= g, sigma = sign(z). c_t = 0 (the
        default) is its limit c_t -> 0+: a stick vertex slips where |lam_T| > g (sigma =
        sign(lam_T)), a slipping one sticks where it slips the wrong way (sigma d > 0). A
        large c_t jumps over the stick region when the slip of an iterate is large against
        g / c_t (a weakly held body: d ~ 1e-1 where g / c_t ~ 1e-4 in the tests) and
        cycled between slipping one way and the other; the limit did not. A vertex that
        gains friction (Coulomb: comes into contact; lam_T = 0 before) takes c_t = c_n:
        it sticks if its motion is inside the cone, |d| <= mu (lb - x_n), else it slips
        against d (sticking it first made a vertex landing with a large d pull itself off
        again, and the iterations cycled).
        """
        active_old, stick_old, sigma = sets
        lt = lamN - self.c_n * (xn - self.lb)
        active = lt > 0.0
        g = self.mu * np.maximum(lt, 0.0) if s is None else s
        if self.c_t > 0.0:
            z = lamT - self.c_t * d
            stick = (np.abs(z) <= g) & (g > 0.0)
            return active, stick, np.where(z > 0.0, 1.0, np.where(z < 0.0, -1.0, sigma))
        had = active_old if s is None else np.ones(len(g), dtype=bool)      # friction before
        new = ~had & (g > 0.0)
        sigma = np.where(stick_old & (lamT != 0.0), np.sign(lamT), sigma)
        sigma = np.where(new & (d != 0.0), -np.sign(d), sigma)
        slip = np.where(stick_old, np.abs(lamT) > g,
                        np.where(had, sigma * d <= 0.0, self.c_n * np.abs(d) > g))
        stick = ~slip & (g > 0.0)
        return active, stick, sigma

    def _newton(self, xref, tol, s, max_it=None):
        """The semi-smooth Newton iterations of one step (s: Tresca thresholds; None:
        Coulomb, the slip force linear in lam_N). Returns ``{"its"}``.

        As in :meth:`SemismoothNewton.newton <sdm_dolfinx.solvers.semismooth.SemismoothNewton.newton>`,
        when the number of violated conditions has not decreased for 3 iterations only the
        violated vertex of largest global index changes (its normal status, else its
        tangential one: Murty's rule), which ends the cycles that full updates can fall
        into (measured: a weakly held block pulled off the plane under Tresca friction).
        For Tresca the problem is a box-constrained LCP with the SPD matrix K^-1 on the
        contact dofs, for which single exchanges terminate.
        """
        m, (active, stick, sigma) = self.m, self._sets
        partner = np.concatenate([np.zeros(m, dtype=np.int64), np.arange(m)])   # t_i -> n_i
        target = np.concatenate([self.lb, xref])
        murty = MurtyRule(self.K.getOwnershipRange()[0] + self.ndofs, self.comm)
        max_it = max_it or self.max_it
        for it in range(1, max_it + 1):
            friction = active if s is None else np.ones(m, dtype=bool)
            stick = stick & friction
            slip = friction & ~stick
            a, c = np.zeros(2 * m), np.zeros(2 * m)
            if s is None:
                c[m:] = np.where(slip, sigma * self.mu, 0.0)
            else:
                a[m:] = np.where(slip, sigma * s, 0.0)
            xc, r = self.system.system(np.concatenate([active, stick]), target, a, c, partner)
            xn, d, lamN, lamT = xc[:m], xc[m:] - xref, r[:m], r[m:]
            g = np.where(friction, self.mu * lamN if s is None else s, 0.0)
            bad_n = np.where(active, lamN < -tol, xn < self.lb - tol / self.c_n)
            bad_t = np.where(stick, np.abs(lamT) > g + tol, slip & (sigma * d > tol / self.k_t) & (g > tol))
            n_bad = self.comm.allreduce(int(np.count_nonzero(bad_n | bad_t)), op=MPI.SUM)
            self.lam, self.lam_t = lamN, lamT
            self.active, self.stick, self.slip = active, stick, slip & (g > 0.0)
            self._sets = sets = (active, stick, sigma)
            if self.monitor and self.comm.rank == 0:
                print(f"  {it:3d} frictional Newton: {n_bad} conditions violated (tolerance {tol:.3e})", flush=True)
            if n_bad == 0:
                return {"its": it}
            new = self._predict(xn, lamN, lamT, d, sets, s)
            one = murty.single(n_bad, bad_n | bad_t)
            if one is not None:
                normal = one & bad_n
                tangential = one & ~bad_n | (normal if s is None else False)   # Coulomb: gains friction
                new = (np.where(normal, new[0], active),) + tuple(np.where(tangential, n, o)
                                                                  for n, o in zip(new[1:], sets[1:]))
            active, stick, sigma = new
        raise VIError(f"frictional semi-smooth Newton ({'Coulomb' if s is None else 'Tresca'}) did not "
                      f"converge in {max_it} iterations ({n_bad} conditions still violated)")

    def _step(self, xref, tol):
        """One step by the chosen method; ``auto``: Newton, then the fixed point from the
        step's start if Newton has not converged in :data:`AUTO_NEWTON_MAX_IT` iterations."""
        if self.law == "tresca" or self.coulomb == "newton":
            return self._newton(xref, tol, self.s)
        lam0, sets0 = self.lam, self._sets
        if self.coulomb == "auto":
            its = min(self.max_it, AUTO_NEWTON_MAX_IT)
            try:
                return self._newton(xref, tol, None, its)
            except VIError as e:
                self._sets, failed = sets0, e
        else:
            its, failed = 0, None
        try:
            info = self._fixed_point(xref, tol, self.mu * lam0)
        except VIError as e:
            raise VIError(f"{failed}; then {e}" if failed else str(e)) from None
        return {**info, "its": info["its"] + its}

    def _fixed_point(self, xref, tol, s):
        """Coulomb as Tresca problems with s = mu lam_N of the previous one, until s changes
        by at most the tolerance. Returns ``{"its", "outer"}``."""
        its = 0
        for k in range(1, self.max_it + 1):
            its += self._newton(xref, tol, s)["its"]
            s_new = self.mu * self.lam
            change = self.comm.allreduce(float(np.max(np.abs(s_new - s), initial=0.0)), op=MPI.MAX)
            if change <= tol:
                return {"its": its, "outer": k}
            s = s_new
        raise VIError(f"Coulomb fixed point did not converge in {self.max_it} Tresca solves "
                      f"(thresholds still change by {change:.3e} > {tol:.3e})")

    def destroy(self):
        self.system.destroy()
        self.fac.destroy()

