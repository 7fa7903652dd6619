"""Prescribed displacements: a Problem's named boundary parts with data u = u_D(x, t) that may move.

A :class:`DirichletPart` is data, like the Problem that holds it; the discretisation finds its
dofs (:mod:`sdm_dolfinx.method.dirichlet`), the schemes that take it say at which time their
iterate takes the data (:meth:`sdm_dolfinx.schemes.base.Scheme.dirichlet_iterate`), and the run
reports its reactions and their work (:mod:`sdm_dolfinx.run.prescribed`).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Optional

import numpy as np
import numpy.typing as npt

from sdm_dolfinx.problems.errors import ProblemInputError

if TYPE_CHECKING:
    from dolfinx.mesh import Mesh

#: ``mesh -> local entity (vertex or facet) indices``
MeshEntities = Callable[["Mesh"], npt.ArrayLike]


#: the letters of the components in column names (``reaction_<part>_<x|y|z>``)
AXES = "xyz"


@dataclass
class DirichletPart:
    """A named boundary part where u (or some of its components) follows prescribed, possibly
    time-dependent, data u = u_D(x, t): a clamp, a moving end, a punch pushing one component.

    Attributes:
        name: the part's name (letters, digits, ``_``): its reaction columns are
            ``reaction_<name>_<x|y|z>`` per prescribed component (``reaction_<name>`` for a scalar u).
        facets: ``mesh -> local facet indices`` of the part (as ``dirichlet_facets``).
        value: ``value(x, t) -> values`` at the points x of shape (3, n) at time t: an array that
            broadcasts to u's value shape times n ((gdim, n) for a vector u, (n,) for a scalar
            u; a number is the same value everywhere); only the rows of ``components`` are used.
            Evaluated at the part's dofs of W^h at every step (the scheme says at which times).
        components: the prescribed components of a vector u (e.g. ``(1,)``: u_y only, the other
            components free, such as a frictionless punch), None for all of them (and for a
            scalar u).
        velocity: ``velocity(x, t)``, the rate du_D/dt of the data, read at t = 0 only: the
            scheme's velocity unknown on the part starts from it (None: 0, data that start at
            rest, such as a ramp d(t) = V t^2 / (2 t_r) or a(1 - cos(w t))). A wrong one makes the
            part's velocity alternate from step to step (the midpoint rule's V^{n+1} =
            2 (U^{n+1} - U^n)/dt - V^n), which the body feels through the mass.

    The initial displacement on the part is value(x, 0) (whatever u0 says there).
    """
    name: str
    facets: MeshEntities
    value: Callable[[npt.NDArray[np.float64], float], npt.ArrayLike]
    components: Optional[Sequence[int]] = None
    velocity: Optional[Callable[[npt.NDArray[np.float64], float], npt.ArrayLike]] = None

    def axes(self, shape: tuple[int, ...]) -> tuple[int, ...]:
        """The prescribed components for u of value ``shape`` (``(0,)`` for a scalar u)."""
        if not shape:
            return (0,)
        return tuple(range(shape[0])) if self.components is None else tuple(int(c) for c in self.components)

    def columns(self, shape: tuple[int, ...]) -> tuple[str, ...]:
        """Its reaction columns: ``reaction_<name>_<x|y|z>`` per prescribed component, or
        ``reaction_<name>`` for a scalar u."""
        if not shape:
            return (f"reaction_{self.name}",)
        return tuple(f"reaction_{self.name}_{AXES[c]}" for c in self.axes(shape))

    def values(self, x: npt.NDArray[np.float64], t: float, shape: tuple[int, ...],
               rate: bool = False) -> npt.NDArray[np.float64]:
        """value(x, t) (``rate``: velocity(x, t), 0 without one) as an array of shape (value size, n)
        (ProblemInputError if it cannot be)."""
        n = x.shape[1]
        full = (shape[0], n) if shape else (1, n)
        f = self.velocity if rate else self.value
        what = "velocity" if rate else "value"
        try:
            v = np.asarray(0.0 if f is None else f(x, t), dtype=float)
        except TypeError as e:              # value(x) for value(x, t), most often: say which part, in one line
            raise ProblemInputError(f"Dirichlet part {self.name!r}: {what}(x, t) failed ({e}); it takes the points x "
                                    f"(3, n) and the time t") from None
        try:
            v = np.broadcast_to(v if shape else v.reshape((1,) + v.shape) if v.ndim else v, full)
        except ValueError:
            raise ProblemInputError(f"Dirichlet part {self.name!r}: {what}(x, t) returned "
                                    f"shape {v.shape} for x of "
                                    f"shape {x.shape}; it must broadcast to {full if shape else (n,)}") from None
        return v

    def describe(self, shape: tuple[int, ...]) -> dict[str, Any]:
        """What run.json (and a checkpoint's identity) records of the part."""
        return {"name": self.name, "components": list(self.axes(shape))}



def validate_parts(problem: str, parts: Sequence[DirichletPart], shape: tuple[int, ...]) -> None:
        """Refuse Dirichlet parts that are not DirichletParts, unnamed or twice named, or name
        components u does not have (one line)."""
        names: list[str] = []
        for part in parts:
            if not isinstance(part, DirichletPart):
                raise ProblemInputError(f"problem {problem!r}: dirichlet_parts must hold DirichletPart(name, facets, "
                                        f"value, components) entries (got {type(part).__name__})")
            if not isinstance(part.name, str) or not part.name.isidentifier() or part.name in names:
                raise ProblemInputError(f"problem {problem!r}: a Dirichlet part's name must be a distinct identifier "
                                        f"(letters, digits, _), used in its columns reaction_<name>_<x|y|z> (got "
                                        f"{part.name!r})")
            names.append(part.name)
            if not callable(part.facets) or not callable(part.value) or not (part.velocity is None
                                                                              or callable(part.velocity)):
                raise ProblemInputError(f"problem {problem!r}: Dirichlet part {part.name!r}: facets (mesh -> facets), "
                                        f"value (x, t -> values) and velocity (x, t -> values, or None) must be "
                                        f"callables")
            comps = part.components
            if comps is not None:
                n = shape[0] if shape else 0
                seq = isinstance(comps, (tuple, list, np.ndarray))       # components=1 is not (1,)
                bad = [c for c in (comps if seq else [comps]) if isinstance(c, bool)
                       or not isinstance(c, (int, np.integer)) or not 0 <= c < n]
                bad = bad or ([comps] if not seq else [])
                if not shape or bad or not len(comps) or len(set(comps)) != len(comps):
                    raise ProblemInputError(
                        f"problem {problem!r}: Dirichlet part {part.name!r}: components must be distinct integers "
                        f"in 0..{n - 1} for u of shape {shape}, or None for all of them (got {comps!r})"
                        if shape else f"problem {problem!r}: Dirichlet part {part.name!r}: a scalar u has no "
                                      f"components; leave components at None")

