"""The catalogue of the method comparison: every method as a named combination of run options.

A method is four independent choices (docs: the issue's shared design): the pair and its mass
(``pair``, ``mass``), where the constraint acts (``constrain``), the time scheme (``scheme``,
``hht_alpha``, ``restitution``) and the contact treatment (``contact``, ``penalty``,
``nitsche_theta``, ``nitsche_gamma0``). Each entry names the paper it follows, so that a row of
the comparison says what was run; where the literature leaves a choice open the entry says which
one is taken. A combination a problem cannot run is refused by the method layer itself (one
line, e.g. a pair without an element on the problem's cells): the comparison records that line.

The standard-mass methods use P1/P1 as GetFEM's demo does (``u_degree = 1``); the singular dynamic
method uses the paper's pairs: P2/P1 everywhere (1-D included), P1+/P0 on triangles.
"""
from dataclasses import dataclass

from sdm_dolfinx.run import options as run_options

#: the run options a method may set (flat, as run.json's: the pair and its mass, and the options of
#: the method group: where K^h acts, the contact treatment, the schemes' and treatments' options),
#: with the table's defaults
METHOD_OPTIONS = {k: v for k, v in run_options.complete({}).items()
                  if k in ("pair", "mass", "scheme") or k in run_options.method_names()}


@dataclass(frozen=True)
class Method:
    """One method of the comparison.

    Attributes:
        name: the ``--methods`` name (also the run folders' name).
        options: run options (keys of :data:`METHOD_OPTIONS`); the others at simulate's defaults.
        description: one line: what is run.
        follows: the paper or book it follows.
        cls: Doyen-Ern-Piperno's class (exact / penalty / Nitsche / velocity / modified mass) or ours.
        needs_2d: refused on 1-D problems, with ``reason_1d``.
    """
    name: str
    options: dict
    description: str
    follows: str
    cls: str
    needs_2d: bool = False
    reason_1d: str = ""

    def run_options(self):
        """The method's run options, every key of :data:`METHOD_OPTIONS` present."""
        return {**METHOD_OPTIONS, **self.options}

    def refusal(self, gdim):
        """A one-line reason this method does not run on a ``gdim``-dimensional problem (None: try it)."""
        if self.needs_2d and gdim < 2:
            return self.reason_1d
        return None


_DEP = "Doyen, Ern, Piperno, SIAM J. Sci. Comput. 33 (2011) 223-249"
_SDM = "Renard, J. Comput. Appl. Math. 234 (2010) 906-923"
_CHR = "Chouly, Hild, Renard, ESAIM: M2AN 49 (2015) 481-502 and 503-528"
_KLR = "Khenous, Laborde, Renard, Eur. J. Mech. A/Solids 27 (2008) 918-932"
_NEWMARK = "Newmark, J. Eng. Mech. Div. 85 (1959) 67-94; " + _DEP + " (class 1)"

CATALOGUE = [
    Method("sdm-p2p1", {"pair": "P2/P1", "scheme": "midpoint"},
           "singular dynamic method, P2/P1, midpoint, contact at the vertices (exact)", _SDM, "modified mass"),
    Method("sdm-p2p1-be", {"pair": "P2/P1", "scheme": "backward-euler"},
           "singular dynamic method, P2/P1, backward Euler (dissipative), contact at the vertices", _SDM,
           "modified mass"),
    Method("sdm-p1bp0", {"pair": "P1+/P0", "scheme": "midpoint"},
           "singular dynamic method, P1+/P0 (Lemma 2: well-posed), midpoint", _SDM, "modified mass"),
    Method("sdm-nodes", {"pair": "P2/P1", "scheme": "midpoint", "constrain": "nodes"},
           "singular dynamic method, P2/P1, midpoint, contact at every boundary node (mid-edge nodes too)",
           _SDM, "modified mass", needs_2d=True,
           reason_1d="in 1-D the contact boundary is one vertex: constraining its nodes is sdm-p2p1"),
    Method("redistributed", {"pair": "P1/P1", "mass": "redistributed", "scheme": "newmark"},
           "mass redistribution (no inertia at the contact nodes), P1, Newmark beta = 1/4, exact contact on "
           "U^{n+1} (the implicit Newmark of GetFEM's demo with mass_matrix_type = 1)", _KLR, "modified mass"),
    Method("redistributed-midpoint", {"pair": "P1/P1", "mass": "redistributed", "scheme": "midpoint"},
           "mass redistribution, P1, midpoint scheme with the constraint on U^{n+1/2} (energy conserving)",
           _KLR, "modified mass"),
    Method("standard-midpoint", {"pair": "P1/P1", "scheme": "midpoint"},
           "standard P1 mass, midpoint, exact contact (the paper's Fig. 4: unstable)", _SDM + "; " + _DEP,
           "exact"),
    Method("standard-newmark", {"pair": "P1/P1", "scheme": "newmark"},
           "standard P1 mass, Newmark beta = 1/4 gamma = 1/2, exact contact on U^{n+1}", _NEWMARK, "exact"),
    Method("hht", {"pair": "P1/P1", "scheme": "hht", "hht_alpha": -0.1},
           "standard P1 mass, HHT-alpha (alpha = -0.1), exact contact on U^{n+1}",
           "Hilber, Hughes, Taylor, Earthq. Eng. Struct. Dyn. 5 (1977) 283-292; " + _DEP, "exact"),
    Method("central-difference", {"pair": "P1/P1", "mass": "redistributed", "scheme": "central-difference"},
           "explicit central differences (Newmark beta = 0) on the redistributed P1 mass, exact contact at "
           "the massless contact node (GetFEM's demo: an explicit scheme needs a modified mass for exact "
           "contact)", _KLR + "; " + _DEP, "modified mass"),
    Method("central-difference-penalty", {"pair": "P1/P1", "mass": "row-sum", "scheme": "central-difference",
                                          "contact": "penalty"},
           "explicit central differences on the row-sum lumped P1 mass, penalty contact (evaluated at U^n)",
           _DEP + " (class 2)", "penalty"),
    Method("penalty-midpoint", {"pair": "P1/P1", "scheme": "midpoint", "contact": "penalty"},
           "standard P1 mass, midpoint, penalty contact (its energy in the balance)", _DEP + " (class 2)",
           "penalty"),
    Method("nitsche-theta1", {"pair": "P1/P1", "scheme": "midpoint", "contact": "nitsche", "nitsche_theta": 1.0},
           "standard P1 mass, midpoint, Nitsche contact theta = 1 (symmetric)", _CHR, "Nitsche"),
    Method("nitsche-theta0", {"pair": "P1/P1", "scheme": "midpoint", "contact": "nitsche", "nitsche_theta": 0.0},
           "standard P1 mass, midpoint, Nitsche contact theta = 0", _CHR, "Nitsche"),
    Method("nitsche-theta-1", {"pair": "P1/P1", "scheme": "midpoint", "contact": "nitsche",
                               "nitsche_theta": -1.0},
           "standard P1 mass, midpoint, Nitsche contact theta = -1 (skew-symmetric)", _CHR, "Nitsche"),
    Method("paoli-schatzman-e0", {"pair": "P1/P1", "scheme": "paoli-schatzman", "restitution": 0.0},
           "standard P1 mass, Paoli-Schatzman central differences with an impact law, restitution e = 0",
           "Paoli, Schatzman, SIAM J. Numer. Anal. 40 (2002) 702-733 and 734-768; " + _DEP + " (class 4)",
           "velocity"),
    Method("taylor-flanagan", {"pair": "P1/P1", "scheme": "taylor-flanagan"},
           "standard P1 mass, Taylor-Flanagan explicit scheme (the contact node's velocity and acceleration "
           "corrected after the predictor)", "Taylor, Flanagan, Sandia report SAND86-0594 (1987); "
           + _DEP + " (class 4)", "velocity"),
]
METHODS = {m.name: m for m in CATALOGUE}


def select(text):
    """The methods of ``--methods``: ``all`` or a comma-separated list of names (ValueError, one
    line naming the choices, for an unknown one)."""
    names = [s.strip() for s in str(text).split(",") if s.strip()]
    if not names:
        raise ValueError("--methods needs 'all' or a comma-separated list of method names")
    if names == ["all"]:
        return list(CATALOGUE)
    unknown = [n for n in names if n not in METHODS]
    if unknown:
        raise ValueError(f"unknown method(s) {', '.join(unknown)}; choose 'all' or among {', '.join(METHODS)}")
    return [METHODS[n] for n in dict.fromkeys(names)]


def describe():
    """One line per method: name, description, the paper it follows (``compare --list``)."""
    return [f"{m.name:28s} {m.description} [{m.follows}]" for m in CATALOGUE]
