"""A run of the study as data (:class:`Run`: the problem, its parameters, the run options) and
the paper's tables its cost estimate reads; the studies (:mod:`sdm_dolfinx.paper.design`,
:mod:`sdm_dolfinx.validation.friction_study`) build their runs from it, and :func:`config_text`
writes one as the TOML file the command line reads.
"""
import json
import math
from dataclasses import dataclass
from pathlib import Path

from sdm_dolfinx import problems
from sdm_dolfinx.problems.disc_mesh import LEVEL_DOFS
from sdm_dolfinx.run import num_steps

#: Table 2 of the paper: level -> (dt, h in mm, dofs, relative H1 error in % or None)
PAPER_TABLE2 = {1: (8e-4, 2.0, 622, 5.86), 2: (4e-4, 1.0, 2782, 4.41), 3: (2e-4, 0.5, 11306, 2.57),
                4: (1e-4, 0.25, 45706, 1.42), 5: (5e-5, 0.14, 126892, 0.43), 6: (2.5e-5, 0.07, 511386, None)}
#: the paper's own meshes (GetFEM's ``tests/meshes``): Table 2 row -> file; rows 5 and 6
#: (``disc_P2_h0_3``, ``disc_P2_h0.075``) are not available: our gmsh levels 5 and 6 stand in
PAPER_MESHES = {1: "disc_P2_h4.mesh", 2: "disc_P2_h2.mesh", 3: "disc_P2_h1.mesh", 4: "disc_P2_h0_5.mesh"}
#: run options written before the problem's parameters in a TOML file (the rest after them)
_HEAD_OPTIONS = ("pair", "mass", "scheme")


@dataclass(frozen=True)
class Run:
    """One run of the study: ``simulate(problem, params, **grouped(options))``.

    ``params`` (the problem's declared parameters) and ``options`` (run options, flat as
    ``run.json``'s ``run_options`` and the TOML keys: :mod:`sdm_dolfinx.run.options`) are what
    define the run's results and files; a folder holding a run with the same values is up to date.
    """
    name: str
    problem: str
    params: dict
    options: dict

    @property
    def steps(self):
        return num_steps(self.options["T"], self.options["dt"])

    def config(self):
        """The run as TOML keys (the command-line options without ``--``) -> values, in the
        order of the paper's configuration files."""
        spec = problems.get(self.problem)
        opt = {k.replace("_", "-"): v for k, v in self.options.items()}
        head = [(k, v) for k, v in opt.items() if k in _HEAD_OPTIONS]
        tail = [(k, v) for k, v in opt.items() if k not in _HEAD_OPTIONS]
        return dict(head + [(spec.param(k).option, v) for k, v in self.params.items()] + tail)

    def command_line(self):
        """``PROBLEM --option value ...``: the command that computes the same run (without --out)."""
        args = [self.problem]
        for k, v in self.config().items():
            args += [f"--{k}", repr(v) if isinstance(v, float) else str(v)]
        return " ".join(args)

    def matches(self, info):
        """True when ``info`` (a run.json) describes this run: same problem, and the same
        values of every parameter and run option this run sets."""
        described = info.get("problem") or {}
        args, opts = described.get("args"), info.get("run_options")
        if described.get("name") != self.problem or args is None or opts is None:
            return False
        return (all(_same(args.get(k), v) for k, v in self.params.items())
                and all(_same(opts.get(k), v) for k, v in self.options.items()))

    @property
    def dim(self):
        """dim W^h (for the cost estimate)."""
        if self.problem == "disc":
            if "mesh_file" in self.params:             # one of the paper's meshes
                row = {f: r for r, f in PAPER_MESHES.items()}.get(Path(self.params["mesh_file"]).name, 1)
                return PAPER_TABLE2[row][2]
            lev = self.params["level"]
            return LEVEL_DOFS.get(lev, 4 * LEVEL_DOFS[6] * 4 ** (lev - 6))
        if self.problem == "block":                    # P2 on nx x ny squares (the friction runs)
            return 2 * (2 * self.params["nx"] + 1) * (2 * self.params["ny"] + 1)
        n = self.params["N"]
        pair = self.options["pair"]
        if pair.startswith("P2"):
            return (2 * n + 1) ** 2
        return (n + 1) ** 2 + (2 * n * n if pair.startswith("P1+") else 0)

    def estimate(self):
        """Seconds, serial, on the reference machine (2 cores shared with other work): a fit
        to the wall times of a full study's runs (a quiet machine is faster)."""
        d = self.dim
        if self.problem == "disc":       # levels 3-6 with --linear auto: 9 s, 51 s, 4.4 min, 26 min
            return 1.0 + 1.5e-4 * d + self.steps * 3e-5 * d ** 0.84
        return 1.0 + self.steps * (1.5e-3 + 3e-6 * d)


def _same(a, b):
    """Equal values; floats to round-off (a value read back from JSON)."""
    if isinstance(b, float) or isinstance(a, float):
        try:
            return math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=0.0)
        except (TypeError, ValueError):
            return False
    return a == b


def _toml_value(v):
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, float):
        return repr(v)
    return str(v)


def config_text(run, title, source="Renard 2010"):
    """The TOML file of ``run`` (``python -m sdm_dolfinx PROBLEM --config FILE`` computes it)."""
    lines = [f"# {source}, {title}",
             "# generated by scripts/gen_configs.py from the study that defines this run: do not edit by hand",
             f"# python -m sdm_dolfinx {run.problem} --config THIS_FILE --out DIR", f'problem = "{run.problem}"']
    lines += [f"{k} = {_toml_value(v)}" for k, v in run.config().items()]
    return "\n".join(lines) + "\n"
