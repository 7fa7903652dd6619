"""Gap rows against rigid obstacles: the constraint phi(a_i + u(a_i), t) >= 0 at the constrained nodes.

A Problem that declares ``obstacles`` (signed distances phi(x, t) > 0 outside each obstacle, unit
normal n = grad phi: :mod:`sdm_dolfinx.obstacles`) constrains every constrained node a_i
(the vertices of ``constraint_vertices``; with ``constrain="nodes"`` every node of W^h on the
constrained boundary) by the nearest obstacle: phi_i(y) = min over the obstacles.

**Linearisation, at the current configuration.** A step from (U^n, t_n) to t_{n+1} imposes, on the
scheme's constrained iterate X (the midpoint scheme's U^{n+1/2}, backward Euler's U^{n+1}), the
row linearised at the node's position y_i = a_i + U^n_i at the start of the step:

    n_i . X_i >= n_i . U^n_i - phibar_i,        phibar_i = (1 - w) phi_i(y_i, t_n) + w phi_i(y_i, t_{n+1}),

with n_i the same combination of the normals (normalised) and w the scheme's ``bound_weight``
(midpoint 1/2, backward Euler 1: a fixed obstacle has phibar = phi(y_i)). This is the axis-aligned
bound u_c >= g of a plane whose normal is e_c exactly. The linearisation error of a row is
phi(y + d) - phi(y) - n . d = O(|d_t|^2 / R) for a tangential move d_t of the node during the step
on an obstacle of curvature radius R (0 for a plane): the midpoint scheme keeps a node in sustained
contact on a curved obstacle to within O(|V| dt)^2 / R, alternating in sign (it constrains the
midpoint), and the energy balance holds to the same order (E^{n+1} - E^n = sum_i lam_i n_i .
(U^{n+1}_i - U^n_i), zero where the row holds with phi_i(y_i) = 0). The rows are recomputed
before every step; the step solver caches K^-1 columns per dof, so a normal that turns costs no
new solve (:mod:`sdm_dolfinx.solvers.gap_newton`).

**The obstacle's work.** A moving obstacle (``Obstacle.moves``) does the work sum_i lam_i
(phi_i(y_i, t_n) - phi_i(y_i, t_{n+1})) on the body in a step (for a plane moving along its normal
exactly the moving bound's lam (g(t_{n+1}) - g(t_n)), :mod:`sdm_dolfinx.schemes.midpoint`): the
column ``obstacle_work``.

**Gaps.** The time series' gaps are the true signed distances phi(a_i + U_i, t) (not linearised):
``gap_min_boundary`` at every node of W^h on the constrained boundary, the penetration nobody
could see otherwise.
"""
from __future__ import annotations

from typing import Any, Optional

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.method.body_rows import refusal as body_refusal
from sdm_dolfinx.method.errors import DiscretisationError
from sdm_dolfinx.method.dofs import where_least
from sdm_dolfinx.problems.base import label


Array = npt.NDArray[np.float64]


def nearest(obstacles, y: Array, t: float, weight: Optional[float] = None, t1: Optional[float] = None):
    """(phi (n,), normal (3, n), which (n,)) of the nearest of ``obstacles`` at the points y (3, n) at
    time t; with ``weight`` w and ``t1``: the combination (1 - w) f(t) + w f(t1) of each obstacle's
    phi and normal (normal renormalised) before the nearest is chosen."""
    n = y.shape[1]
    best, normal, which = np.full(n, np.inf), np.zeros((3, n)), np.zeros(n, dtype=np.int32)
    for k, ob in enumerate(obstacles):
        phi, nrm = (np.asarray(a, dtype=float) for a in ob.distance(y, t))
        if weight is not None and weight != 0.0:
            phi1, nrm1 = (np.asarray(a, dtype=float) for a in ob.distance(y, t1))
            phi, nrm = (1.0 - weight) * phi + weight * phi1, (1.0 - weight) * nrm + weight * nrm1
            norm = np.linalg.norm(nrm, axis=0)
            nrm = nrm / np.where(norm > 0, norm, 1.0)
        closer = phi < best
        best[closer], normal[:, closer], which[closer] = phi[closer], nrm[:, closer], k
    return best, normal, which


def refusal(integ: Any, scheme: Any, vi_solver: str, linear: str) -> Optional[str]:
    """The one-line refusal of what the gap rows (obstacles, the weighted gap) do not take yet, or None
    (also without them). ``integ``: the Integrator being built (its discretisation, contact, friction)."""
    d = integ.discretisation
    if getattr(d, "body_rows", None) is not None:
        return body_refusal(integ, scheme, vi_solver, linear)
    if d.obstacle_rows is None and getattr(d, "weighted_rows", None) is None:
        return None
    what = (f"problem {d.problem.name!r} has obstacles" if d.obstacle_rows is not None
            else "constrain 'weighted' (the weighted gap's rows)")
    if scheme.bound_weight is None:
        return f"{what}, which scheme {scheme.name!r} does not take: use the midpoint or backward-euler scheme"
    if integ.block and d.obstacle_rows is None:     # the rows are in W's numbering, K the (U, V) block system's
        return f"{what}, which mass 'consistent' (the (U, V) block system) does not take yet: use mass 'lumped'"
    takes = ("exact", "penalty") if d.obstacle_rows is None else ("exact", "penalty", "nitsche")
    if integ.contact not in takes:
        return f"{what}, which contact {integ.contact!r} does not take yet: use contact {' or '.join(map(repr, takes))}"
    if integ.contact == "nitsche" and d.obstacle_rows is not None and d.obstacle_rows.moves:
        return f"{what} that move, which contact {integ.contact!r} does not take yet: use contact 'exact' or 'penalty'"
    snes = vi_solver in ("vinewtonrsls", "vinewtonssls") and d.obstacle_rows is not None
    if snes and (integ.contact != "exact" or integ.friction is not None or linear not in ("auto", "lu")):
        return (f"{what}: vi_solver {vi_solver!r} takes the exact frictionless contact with linear 'auto' or 'lu' "
                f"only (got contact {integ.contact!r}, linear {linear!r})")
    if not snes and (vi_solver != "ssn" or linear not in ("auto", "schur")):
        return (f"{what}: their gap rows are solved by the semi-smooth Newton with linear strategy schur"
                f"{' (or, against obstacles, by SNES VI)' if d.obstacle_rows is not None else ''} only "
                f"(got vi_solver {vi_solver!r}, linear {linear!r})")
    return None


class ObstacleRows:
    """The gap rows of a Discretisation ``d`` whose Problem declares ``obstacles`` (see the module).

    Attributes:
        dofs: (m, gdim) owned local dofs of W^h of the m constrained nodes of this rank (row i reads
            dofs[i]; the constrained dofs ``cdofs`` are their ``constraint_component`` entries).
        x: (3, m) the nodes' reference coordinates.
        moves: some obstacle moves.
    """

    def __init__(self, d: Any) -> None:
        p = d.problem
        self.obstacles = tuple(p.obstacles)
        self.comm = d.comm
        self.gdim = int(p.shape[0])
        bs = d.W.dofmap.index_map_bs
        c = p.constraint_component or 0
        blocks = (np.asarray(d.cdofs, dtype=np.int64) - c) // bs
        self.dofs = (blocks[:, None] * bs + np.arange(self.gdim)[None, :]).astype(np.int32)
        #: the rows' entries at Dirichlet dofs (constant data: a Dirichlet part at a constrained node is
        #: refused), which X does not change: their terms n_c X_c = n_c U^n_c leave the row
        self.free = ~np.isin(self.dofs, np.asarray(d.ddofs))
        moving = np.concatenate([np.asarray(k, dtype=np.int64) for k in d.part_dofs]) if d.part_dofs else np.zeros(0)
        n = d.comm.allreduce(int(np.count_nonzero(np.isin(self.dofs, moving))), op=MPI.SUM)
        if n:
            raise DiscretisationError(f"{label(p)}: a Dirichlet part prescribes {n} components of the nodes the "
                                      f"obstacles constrain (their rows would take its data at the wrong time): leave "
                                      f"the contact boundary out of the parts")
        self.x = np.asarray(d.cx, dtype=float)
        bblocks = (np.asarray(d.bdofs, dtype=np.int64) - c) // bs
        self.bdofs = (bblocks[:, None] * bs + np.arange(self.gdim)[None, :]).astype(np.int32)
        self.bx = np.asarray(d.bx, dtype=float)
        self.moves = any(bool(getattr(ob, "moves", False)) for ob in self.obstacles)
        x = np.asarray(p.mesh.geometry.x)
        ext = np.concatenate([-np.min(x, axis=0, initial=np.inf), np.max(x, axis=0, initial=-np.inf)])
        self.comm.Allreduce(MPI.IN_PLACE, ext, op=MPI.MAX)
        #: the mesh's largest extent along an axis: the scale of the initial state's gap tolerance
        self.size = max(float(np.max(ext[3:] + ext[:3])), 1e-300)
        flat = [ob for ob in self.obstacles if self.gdim == 2 and not getattr(ob, "planar", True)]
        if flat:
            raise DiscretisationError(f"{label(p)}: obstacle {getattr(flat[0], 'kind', type(flat[0]).__name__)!r} "
                                      f"is not a plane-section obstacle (its normals leave the x-y plane): a 2-D "
                                      f"problem takes half-spaces with n_z = 0, balls (discs) centred on z = 0, "
                                      f"cylinders along z, wedges with n1_z = n2_z = 0 and surface meshes of lines")
        self._y: Optional[Array] = None
        self._t: tuple[float, float] = (0.0, 0.0)
        #: (m, gdim) the nearest obstacle's own displacement over the last :meth:`rows`' step at each
        #: constrained node (its material point there at t0, carried to t1; zeros when nothing moves)
        self.carried = np.zeros((len(self.dofs), self.gdim))

    def require_free(self, what: str) -> None:
        """Refuse (one line, collective) ``what`` where a constrained node has a Dirichlet component: the
        nodes' frames would mix it into the normal and tangential unknowns. Unreachable today
        (``dirichlet_facets`` take such a node out of the constraint, Dirichlet parts at constrained
        nodes are refused); kept so that a later change cannot make the frames silently wrong."""
        if not self.comm.allreduce(bool(np.all(self.free)), op=MPI.LAND):
            raise DiscretisationError(f"{what} works in each constrained node's frame, and a constrained node has a "
                                      f"Dirichlet component: not built")

    # ---------------------------------------------------------------- positions and gaps
    def reference(self) -> tuple[Array, Array]:
        """(phi (m,), unit normals (m, gdim)) of the nearest obstacle at this rank's constrained nodes in
        the reference configuration, at t = 0 (the static start's rows; the penalty's stiffness)."""
        phi, nrm, _ = nearest(self.obstacles, self.x, 0.0)
        return phi, np.ascontiguousarray(nrm[:self.gdim].T)

    def _at(self, x: Array, dofs: Array, u: Array) -> Array:
        """The current positions (3, n) of the nodes at reference ``x`` whose dofs are ``dofs``."""
        y = np.array(x, dtype=float, copy=True)
        if len(dofs):
            y[:self.gdim] += u[dofs].T
        return y

    def phi(self, u: Array, t: float, boundary: bool = False) -> Array:
        """The signed distances (local, (n,)) of the constrained nodes (``boundary``: of every node of the
        constrained boundary) at the state ``u`` (an owned array of W^h) at time t."""
        x, dofs = (self.bx, self.bdofs) if boundary else (self.x, self.dofs)
        return nearest(self.obstacles, self._at(x, dofs, u), t)[0] if len(dofs) else np.zeros(0)

    def gap(self, u: Array, t: float, boundary: bool = False) -> float:
        """min of :meth:`phi` over the ranks (+inf without nodes; collective)."""
        return self.comm.allreduce(float(np.min(self.phi(u, t, boundary), initial=np.inf)), op=MPI.MIN)

    def where(self, u: Array, t: float) -> Array:
        """The reference coordinates (gdim,) of the constrained boundary's node nearest to an obstacle."""
        return where_least(self.comm, self.phi(u, t, boundary=True), self.bx)[:self.gdim]

    # ---------------------------------------------------------------- the step's rows
    def rows(self, u: Array, t0: float, t1: float, weight: float) -> tuple[Array, Array]:
        """(coef (m, gdim), g (m,)) of the step from t0 to t1 linearised at the state ``u`` (U^n), for a
        scheme imposing the rows at ``weight`` (see the module); keeps the linearisation point for
        :meth:`work`."""
        self._y, self._t = self._at(self.x, self.dofs, u), (t0, t1)
        if not len(self.dofs):
            return np.zeros((0, self.gdim)), np.zeros(0)
        phi, nrm, which = nearest(self.obstacles, self._y, t0, weight if self.moves else None, t1)
        if self.moves:
            for k, ob in enumerate(self.obstacles):
                at = which == k
                self.carried[at] = (ob.carry(self._y[:, at], t0, t1) - self._y[:, at])[:self.gdim].T
        coef: Array = np.ascontiguousarray(nrm[:self.gdim].T) * self.free.astype(float)
        g = np.einsum("ik,ik->i", coef, u[self.dofs]) - phi
        g[~np.any(coef != 0.0, axis=1)] = -np.inf          # every component fixed: nothing to hold
        return coef, g

    def after_step(self, info: dict, u: Array, t1: float, lam: Array) -> None:
        """``info["gap_end"]``, the true signed distance of U^{n+1} = ``u`` at t_{n+1}, and with moving
        obstacles ``info["obstacle_work"]`` (:meth:`work`; collective)."""
        info["gap_end"] = self.gap(u, t1)
        if self.moves:
            info["obstacle_work"] = self.work(lam)

    def work(self, lam: Array) -> float:
        """The obstacle's work in the last step: sum_i lam_i (phi_i(y_i, t_n) - phi_i(y_i, t_{n+1})) at the
        linearisation points of :meth:`rows` (0 when nothing moves; collective)."""
        if not self.moves or self._y is None:
            return 0.0
        t0, t1 = self._t
        local = 0.0
        if len(self.dofs):
            phi0 = nearest(self.obstacles, self._y, t0)[0]
            phi1 = nearest(self.obstacles, self._y, t1)[0]
            local = float(np.dot(lam, phi0 - phi1))
        return self.comm.allreduce(local, op=MPI.SUM)
