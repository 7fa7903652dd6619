"""A Problem's constraint declarations checked (one line naming the problem): ``obstacles`` and
``contact_pairs`` (:mod:`.contact_pairs`), each instead of ``lower_bound``."""
from __future__ import annotations

from typing import Any

from sdm_dolfinx.problems.contact_pairs import ContactPair
from sdm_dolfinx.problems.errors import ProblemInputError


def validate_obstacles(problem: Any) -> None:
    """Obstacles: objects with ``distance(x, t)``, on a vector problem, instead of ``lower_bound``."""
    obstacles = problem.obstacles
    if isinstance(obstacles, (str, bytes)) or not isinstance(obstacles, (list, tuple)):
        raise ProblemInputError(f"problem {problem.name!r}: obstacles must be a list of obstacles "
                                f"(sdm_dolfinx.obstacles), got {type(obstacles).__name__}")
    if not obstacles:
        if problem.lower_bound is None and not problem.contact_pairs:
            raise ProblemInputError(f"problem {problem.name!r}: lower_bound is None and there are no obstacles "
                                    f"or contact_pairs: declare lower_bound (u_c >= bound), obstacles or contact_pairs")
        return
    bad = [type(o).__name__ for o in obstacles if not callable(getattr(o, "distance", None))]
    if bad:
        raise ProblemInputError(f"problem {problem.name!r}: obstacles must have distance(x, t) (see "
                                f"sdm_dolfinx.obstacles), not {bad[0]}")
    if not problem.shape:
        raise ProblemInputError(f"problem {problem.name!r}: obstacles constrain a displacement vector; a scalar u "
                                f"is bounded by lower_bound")
    if problem.lower_bound is not None or problem.moving_bound:
        raise ProblemInputError(f"problem {problem.name!r}: declare either lower_bound (one component bounded) or "
                                f"obstacles, not both (set lower_bound=None and moving_bound=False)")


def validate_pairs(problem: Any) -> None:
    """Refuse, in one line, contact pairs with another constraint, on a scalar u or a 1-D mesh, or
    that are not :class:`ContactPair` objects."""
    pairs, name = problem.contact_pairs, problem.name
    if isinstance(pairs, (str, bytes)) or not isinstance(pairs, (list, tuple)):
        raise ProblemInputError(f"problem {name!r}: contact_pairs must be a list of ContactPair (got "
                                f"{type(pairs).__name__})")
    if not pairs:
        return
    bad = [type(p).__name__ for p in pairs if not isinstance(p, ContactPair)]
    if bad:
        raise ProblemInputError(f"problem {name!r}: contact_pairs must hold ContactPair objects, not {bad[0]}")
    if not problem.shape:
        raise ProblemInputError(f"problem {name!r}: contact_pairs constrain a displacement vector; a scalar u is "
                                f"bounded by lower_bound")
    others = [what for what, there in (("constraint_vertices", problem.constraint_vertices is not None),
                                       ("lower_bound", problem.lower_bound is not None),
                                       ("obstacles", bool(problem.obstacles)),
                                       ("moving_bound", bool(problem.moving_bound))) if there]
    if others:
        raise ProblemInputError(f"problem {name!r}: with contact_pairs the pairs' slave facets are the constraint: "
                                f"set {', '.join(others)} to None (or empty, False)")
    names = [p.name for p in pairs]
    wrong = [n for n in names if not (isinstance(n, str) and n and n.replace("_", "a").isalnum())]
    if wrong or len(set(names)) != len(names):
        raise ProblemInputError(f"problem {name!r}: contact pair names must be distinct words of letters, digits and "
                                f"'_' (got {', '.join(map(repr, names))})")
