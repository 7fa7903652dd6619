"""``python -m sdm_dolfinx energy DIR``: a finished run's energy history recomputed from its
``state.h5`` (:func:`sdm_dolfinx.post.recompute_energy`), for any declared problem (the run's
problem is rebuilt from its ``run.json`` through the registry, a problem file included).

Bad input (not a run folder, a problem that cannot be rebuilt): one line, exit status 2.
"""
import sys
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx.cli.common import Parser, UsageError, parse_run_folder, say_error
from sdm_dolfinx.post import recompute_energy
from sdm_dolfinx.io import PostprocessError

PROG = "python -m sdm_dolfinx energy"
#: the files a run folder must hold
RUN_FILES = ("run.json", "timeseries.csv", "state.h5")
#: the columns of timeseries.csv the comparison reads
NEEDED_COLUMNS = ("step", "energy")
#: what the command writes
OUTPUT = "energy_recomputed.csv"


def build_parser():
    p = Parser(prog=PROG, description="Recompute the energy history of a run from its state.h5 "
               "(independently of the run's own diagnostics), write DIR/energy_recomputed.csv and "
               "print the largest relative difference to DIR/timeseries.csv.")
    p.add_argument("folder", type=Path, metavar="DIR", help="a run's output folder")
    return p


def check_folder(folder):
    """What would fail only after the whole computation, checked first (rank 0): the time
    series' columns the comparison needs, and that DIR/energy_recomputed.csv can be written."""
    path = folder / "timeseries.csv"
    try:
        with open(path, newline="") as fh:
            header = fh.readline(1 << 16).strip().split(",")
    except (OSError, UnicodeDecodeError) as e:
        raise UsageError(f"cannot read {path}: {getattr(e, 'strerror', None) or e}") from None
    for column in NEEDED_COLUMNS:
        if column not in header:
            raise UsageError(f"{path} has no column '{column}' (its header: {','.join(header)[:120]})")
    out = folder / OUTPUT
    if out.is_dir():
        raise UsageError(f"{out} is a folder: cannot write the result there")
    # os.access says yes to root on a read-only folder: try a temporary file (removed at once)
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as e:
        raise UsageError(f"cannot write {out} ({folder}: {e.strerror or e})") from None


def main(argv=None):
    """``python -m sdm_dolfinx energy DIR``: returns the exit status (0, 2 bad input)."""
    comm = MPI.COMM_WORLD
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_run_folder(PROG, build_parser(), argv, comm, RUN_FILES, "recompute its energy", check_folder)
    if isinstance(args, int):
        return args
    try:
        res = recompute_energy(args.folder, comm)
    except PostprocessError as e:
        return say_error(PROG, e, comm, 2)
    if comm.rank == 0:
        eps = np.finfo(np.dtype(res["stored_dtype"])).eps
        print(f"{args.folder}: energy of {len(res['step'])} stored states -> {args.folder}/energy_recomputed.csv; "
              f"max relative difference to timeseries.csv: {res['max_rel_diff']:.3e} "
              f"(= {res['max_roundoff_ratio'] / eps:.3g} eps of the round-off scale 1/2|U||A||U| + |U||L| + "
              f"1/2|V||M||V|, entrywise absolute values; {res['rows']} common steps; "
              f"state.h5 stores {res['stored_dtype']}, eps = {eps:.1e})", flush=True)
    return 0
