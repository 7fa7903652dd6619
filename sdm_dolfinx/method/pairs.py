"""Registry of (W^h, H^h) pairs: the displacement space, the velocity space and how C is treated.

A pair is pure data; :mod:`sdm_dolfinx.discretisation` turns it into matrices.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from sdm_dolfinx import compat
from sdm_dolfinx.method.errors import DiscretisationError

#: how C = (psi_i, psi_j) enters M = B^T C^-1 B (SDM pairs), or which mass a standard pair
#: (H^h = W^h) uses: its consistent mass, the row-sum lumped mass or the redistributed mass of
#: Khenous, Laborde and Renard (2008), see :mod:`sdm_dolfinx.method.masses`
MASS_TREATMENTS = ("standard", "diagonal", "lumped", "consistent", "row-sum", "redistributed")

#: every cell type a pair may name in :attr:`Pair.cells` (the method wants simplices)
SIMPLEX_CELLS = ("interval", "triangle", "tetrahedron")


@dataclass(frozen=True)
class Pair:
    """A discretisation pair (W^h, H^h).

    Attributes:
        name: the paper's name, e.g. ``"P2/P1"``.
        w: ``(family, degree)`` of W^h, family ``"P+"`` meaning P1 + cubic bubble.
        h: ``(family, degree)`` of H^h, or ``None`` when H^h = W^h (standard Galerkin).
        well_posed: what the paper says (condition (7) proved, observed, or failing).
        cells: the cell types its elements exist on (the rest of the method wants simplices).
            P1+ is P1 + the cell's bubble: degree 3 on a triangle (the paper's), degree 2 on an
            interval (x (1 - x), basix's "Bubble" of degree 2), where P1 + bubble spans exactly
            P2, so that in 1-D P1+/P0 is the pair P2/P0 and P1+/P1 the pair P2/P1 written in a
            hierarchical basis (same W^h, H^h and vertex constraints: the same discrete solution);
            degree 4 on a tetrahedron (basix refuses degree 3 there), for which inf-sup (7) was
            measured (bench/ball_infsup.py): P1+/P0 beta = 0.70, 0.48, 0.42, 0.40 on unit cubes of
            n = 1..4 cells a side and 0.387 / 0.368 on the ball's levels 1 / 2 (levelling off);
            P1+/P1 0.12-0.19 and 0.202 / 0.192.
    """
    name: str
    w: tuple[str, int]
    h: Optional[tuple[str, int]]
    well_posed: str
    cells: tuple[str, ...] = SIMPLEX_CELLS

    def check_cell(self, cell: str) -> None:
        """DiscretisationError (one line, the pairs available on ``cell``) if this pair has no element there."""
        if cell not in self.cells:
            there = [p.name for p in PAIRS.values() if cell in p.cells]
            raise DiscretisationError(
                f"pair {self.name} is not available on {cell} meshes; "
                + (f"the pairs available on {cell} meshes: {', '.join(there)}" if there
                   else "no pair is: the method needs intervals, triangles or tetrahedra"))

    def w_element(self, cell: str, shape: tuple[int, ...] = ()) -> compat.Element:
        """The element of W^h (displacement) on ``cell`` with value shape ``shape``."""
        self.check_cell(cell)
        family, degree = self.w
        if family == "P+":
            return compat.p1_bubble_element(cell, shape)
        return compat.element("Lagrange", cell, degree, shape)

    def h_element(self, cell: str, shape: tuple[int, ...] = ()) -> Optional[compat.Element]:
        """The element of H^h (velocity) on ``cell``, or None for the standard method (H^h = W^h)."""
        if self.h is None:
            return None
        self.check_cell(cell)
        family, degree = self.h
        return compat.element("DG" if degree == 0 else "Lagrange", cell, degree, shape)

    @property
    def standard(self) -> bool:
        """True when H^h = W^h: the standard (consistent mass) Galerkin method."""
        return self.h is None

    def default_mass(self) -> str:
        """The C treatment used unless asked otherwise: exact diagonal (P0), lumped (P1); the
        consistent mass of W^h for a standard pair."""
        if self.h is None:          # standard
            return "standard"
        return "diagonal" if self.h[1] == 0 else "lumped"

    def allowed_masses(self) -> tuple[str, ...]:
        """The C treatments (SDM pairs) or masses (standard pairs) this pair accepts (see
        :data:`MASS_TREATMENTS`): a standard pair's consistent mass, its row-sum lumped mass
        (refused at assembly where row sums vanish: P2 on triangles and tetrahedra) and the
        redistributed mass (:mod:`sdm_dolfinx.method.masses`)."""
        if self.h is None:          # standard
            return ("standard", "row-sum", "redistributed")
        if self.h[1] == 0:
            return ("diagonal",)
        return ("lumped", "consistent")


PAIRS: dict[str, Pair] = {p.name: p for p in [
    Pair("P1+/P0", ("P+", 1), ("P", 0), "proved (Lemma 2, 2-D; observed on tetrahedra)",
         cells=("interval", "triangle", "tetrahedron")),
    Pair("P1/P0", ("P", 1), ("P", 0), "no: dim H >= dim W - N_g"),
    Pair("P1/P1", ("P", 1), None, "no: standard Galerkin, Ker(B) = {0}"),
    Pair("P1+/P1", ("P+", 1), ("P", 1), "observed (no proof in the paper)",
         cells=("interval", "triangle", "tetrahedron")),
    Pair("P2/P1", ("P", 2), ("P", 1), "observed (no proof in the paper)"),
    Pair("P2/P2", ("P", 2), None, "no: standard Galerkin, Ker(B) = {0}"),
]}


def register(pair: Pair) -> Pair:
    """Add a :class:`Pair` to :data:`PAIRS` (so that ``--pair`` and ``simulate(pair=name)`` know
    it); a pair of one's own can also be given to ``simulate`` as the object itself."""
    if not isinstance(pair, Pair):
        raise TypeError(f"register() takes a Pair, got {type(pair).__name__}")
    if pair.name in PAIRS and PAIRS[pair.name] != pair:
        raise ValueError(f"a different pair {pair.name!r} is registered already")
    PAIRS[pair.name] = pair
    return pair


def get_pair(name: str) -> Pair:
    """The registered pair called ``name``; ValueError listing the choices otherwise."""
    try:
        return PAIRS[name]
    except KeyError:
        raise ValueError(f"unknown pair {name!r}; choose one of {', '.join(PAIRS)}") from None
