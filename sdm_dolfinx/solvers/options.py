"""PETSc options of the step solvers: one prefix per solver instance, the shared ``sdm_``
options, the solvers' own ``vi_*`` options and the names of converged reasons.

Each solver instance reads its options under its own prefix (``sdm_1_``, ``sdm_2_``, ... or
the one it was given, the same on every rank), as dolfinx and dolfinx_mpc give each solver
its own: options given to one instance (its ``options`` dict) never reach another one and
never stay in the global database. The documented command-line options under the shared
prefix ``sdm_`` (``-sdm_snes_monitor``, ``-sdm_vi_rtol``, ``-sdm_ksp_type``, ...) still
apply to every instance: :class:`scoped_options` with ``inherit=True`` copies them to the
instance's prefix for the PETSc calls that read them (set-up, factorisations, solves).
"""
import re

from mpi4py import MPI
from petsc4py import PETSc

from sdm_dolfinx.compat import petsc_options_used as options_used
from sdm_dolfinx.solvers.base import VIError

#: the prefix of the options that apply to every solver instance (the command line's -sdm_...)
SHARED_PREFIX = "sdm_"

#: the prefixes :func:`instance_prefix` makes; never copied from one instance to another
_AUTO_PREFIX = re.compile(r"sdm_\d+_")
_last_instance = 0


def instance_prefix(comm, prefix=None):
    """``prefix``, or a new ``sdm_<k>_`` (collective on the mpi4py ``comm``).

    k counts the solvers made in this process; the largest count over the ranks of ``comm``
    is taken so that the prefix is the same on every rank even after a solver was made on
    some ranks only (on COMM_SELF).
    """
    global _last_instance
    if prefix is not None:
        return prefix
    _last_instance = comm.allreduce(_last_instance + 1, op=MPI.MAX)
    return f"{SHARED_PREFIX}{_last_instance}_"


class scoped_options:
    """Context: PETSc options under ``prefix`` for the PETSc calls inside it.

    ``options`` (a dict, keys without the prefix) are defaults: a value already in the
    database wins, unless ``force`` (then it is overridden for the context only). With
    ``inherit``, every shared ``sdm_<key>`` of the database is first copied to
    ``<prefix><key>`` unless that exists: an instance's own ``-sdm_3_<key>`` wins over the
    shared ``-sdm_<key>``, which wins over ``options``. On exit the database is as before,
    except that a shared option whose copy PETSc read is marked used, so that
    ``-options_left`` does not report it (a misspelt one, never read, still is).
    """

    def __init__(self, prefix, options=None, force=False, inherit=False):
        self.prefix, self.options, self.force = prefix, dict(options or {}), force
        self.inherit = inherit and prefix.lower() != SHARED_PREFIX
        self.added, self.saved, self.inherited = [], {}, {}

    def __enter__(self):
        opts = PETSc.Options()
        # getAll reads the database without marking anything used (values cut at blanks)
        present = {k.lower(): v for k, v in opts.getAll().items()}
        if self.inherit:
            for name, value in list(present.items()):
                if not name.startswith(SHARED_PREFIX) or _AUTO_PREFIX.match(name):
                    continue
                key = (self.prefix + name[len(SHARED_PREFIX):]).lower()
                if key not in present:
                    opts.setValue(key, value)
                    present[key] = value
                    self.inherited[key] = name
        for k, v in self.options.items():
            key = self.prefix + k
            if key.lower() in present:
                if not self.force:
                    continue
                self.saved[key] = opts.getString(key)      # overridden for the context only
            else:
                self.added.append(key)
            opts.setValue(key, v)
        return self

    def __exit__(self, *exc):
        opts = PETSc.Options()
        for key in self.added:
            opts.delValue(key)
        for key, v in self.saved.items():
            opts.setValue(key, v)
        for key, name in self.inherited.items():
            if options_used(key):
                opts.hasName(name)          # marks the shared option used
            opts.delValue(key)
        self.added, self.saved, self.inherited = [], {}, {}

    def origin(self, key):
        """The option as the user wrote it, for messages: ``-sdm_<key>`` when inherited."""
        name = self.inherited.get((self.prefix + key).lower())
        return f"-{name}" if name else f"-{self.prefix}{key}"


#: the VI solvers' own options (after the prefix): name -> (parse, valid, what is allowed);
#: :func:`vi_tolerances` and the command line (``cli._petsc_overrides``) check them with these
VI_OPTIONS = {"vi_rtol": (float, lambda v: 0 < v < 1, "a number in (0, 1)"),
              "vi_max_it": (int, lambda v: v >= 1, "an integer >= 1"),
              "vi_monitor": (str, lambda v: v.lower() in ("", "1", "0", "true", "false", "yes", "no"),
                             "true or false (or no value)")}


def vi_tolerances(scope, rtol, max_it):
    """The step solver's own settings, overridable as PETSc options for either VI solver:
    ``-<prefix>vi_rtol`` (complementarity tolerance relative to max|b|),
    ``-<prefix>vi_max_it`` (iterations per step) and ``-<prefix>vi_monitor`` (one line per
    iteration on rank 0). Read inside the instance's :class:`scoped_options` ``scope``: the
    command line wins over its ``options``, which win over the arguments."""
    opts, prefix = PETSc.Options(), scope.prefix
    rtol = opts.getReal(prefix + "vi_rtol", rtol)
    max_it = opts.getInt(prefix + "vi_max_it", max_it)
    monitor = opts.getBool(prefix + "vi_monitor", False)
    for name, value in (("vi_rtol", rtol), ("vi_max_it", max_it)):
        _, valid, allowed = VI_OPTIONS[name]
        if not valid(value):
            raise VIError(f"{scope.origin(name)}: {value!r} is not {allowed}")
    return rtol, max_it, monitor


def ksp_reason_name(reason):
    """The name of a KSP converged reason (``DIVERGED_ITS``, ...)."""
    names = {v: k for k, v in vars(PETSc.KSP.ConvergedReason).items() if isinstance(v, int)}
    return names.get(reason, "unknown")


def snes_reason_name(reason):
    """The name of a SNES converged reason (``DIVERGED_MAX_IT``, ...)."""
    names = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
    return names.get(reason, "unknown")


#: the families of PETSc options the step solvers read under their prefix (``-sdm_`` or an
#: instance's ``-sdm_<k>_``): their own ``vi_*``, ``schur_max_active``, ``gap_max_columns`` and ``inexact_rtol``, the semi-smooth Newton's
#: or PETSc's SNES (``snes_``), its linear solves (``ksp_``, ``pc_``, ``mat_``), the factorisation
#: (``factor_``), the penalty's and the AMG strategies' Krylov solvers (``penalty_``, ``amg_``,
#: ``gamg_``, ``pmg_``)
OPTION_FAMILIES = ("vi_", "snes_", "ksp_", "pc_", "mat_", "factor_", "penalty_", "amg_", "gamg_", "pmg_")
_OPTION = re.compile(r"^(\d+_)?(" + "|".join(OPTION_FAMILIES) + r")\w+$|^(\d+_)?(schur_max_active|gap_max_columns|inexact_rtol)$")


def unknown_option(name):
    """A one-line refusal of the step solver's PETSc option ``name`` (without ``-sdm_`` or with
    it) when it belongs to none of :data:`OPTION_FAMILIES` (no solver would read it: PETSc would
    only list it as unused when the run ends), else None."""
    key = str(name).lstrip("-")
    key = key[len("sdm_"):] if key.startswith("sdm_") else key
    if _OPTION.match(key):
        return None
    return (f"PETSc option -sdm_{key}: no step solver reads it; the step solvers' options are -sdm_"
            f"{', -sdm_'.join(f + '...' for f in OPTION_FAMILIES)}, -sdm_schur_max_active, -sdm_gap_max_columns "
            f"and -sdm_inexact_rtol (docs/running.md)")
