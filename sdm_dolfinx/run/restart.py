"""Continuing a run from its checkpoint, and writing checkpoints (see :mod:`.checkpoint`).

A restart continues exactly: U, V, the active set and the step solver's history
(:mod:`.solver_state`) are restored, so serially the continued run is bit-identical to an
uninterrupted one (time series, every XDMF field, state.h5), contact or not. On several
ranks the new process may partition the mesh differently, and a different partition sums
in another order (MUMPS's parallel factorisation is not even reproducible from run to run
on one partition): there the continued run agrees to round-off (measured up to 1.6e-11
relative), and the files stay consistent because they do not depend on the partition.
"""
import uuid
from pathlib import Path

from sdm_dolfinx.io import checkpoint
from sdm_dolfinx.io.checkpoint import CheckpointError
from sdm_dolfinx.io.run_files import agree
from sdm_dolfinx.run.options import IDENTITY

#: what must be the same for a checkpoint to continue a run: the problem, the package's version,
#: the run options declared part of its identity, the number of ranks
IDENTITY_KEYS = ("problem", "sdm_dolfinx", *IDENTITY, "ranks")
#: what a restart deliberately allowed to continue with a changed source may find changed
SOURCE_KEYS = ("sdm_dolfinx", "problem.source_sha256")
#: what run.json describes of the problem without being part of its identity (derived from its declaration,
#: which ``problem.source_sha256`` and the parameters identify; older versions did not write them)
DESCRIPTIVE_KEYS = ("problem.bodies", "problem.contact_pairs")


def check_identity(saved, now, allow_changed_source=False):
    """A checkpoint continues only the run that wrote it: the first entry that differs is named in
    one line (``problem.parameters.E = 1000.0``, not the whole problem)."""
    skip = DESCRIPTIVE_KEYS + (SOURCE_KEYS if allow_changed_source else ())
    for key in IDENTITY_KEYS:
        diff = first_difference(saved.get(key), now.get(key), key, skip)
        if diff is not None:
            where, was, now_is = diff
            raise CheckpointError(
                f"the checkpoint was written with {where} = {_short(was)}, this run has {_short(now_is)}"
                + (" (restart on the same number of ranks)" if key == "ranks" else ""))
    if not checkpoint.same_fingerprint(saved["mesh"], now["mesh"]):
        raise CheckpointError("the checkpoint was written on a different mesh")


def first_difference(a, b, path, skip=()):
    """(dotted path, a's value, b's value) of the first entry where ``a`` and ``b`` differ (dicts
    compared key by key, entries in ``skip`` ignored), or None when they agree."""
    if path in skip:
        return None
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            diff = first_difference(a.get(k), b.get(k), f"{path}.{k}", skip)
            if diff is not None:
                return diff
        return None
    return None if a == b else (path, a, b)


def _short(v):
    """A value for a one-line message (at most 60 characters)."""
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _check_complete(data, meta, path):
    """A run's checkpoint holds these (a damaged or foreign .npz may not)."""
    missing = [k for k in ("U", "U_x", "V", "V_x", "active_x") if k not in data]
    if not isinstance(meta, dict):
        missing.append("meta")
    else:
        missing += [k for k in ("identity", "step", "run_id") if k not in meta]
        if not missing and not (isinstance(meta["identity"], dict) and isinstance(meta["step"], int)
                                and isinstance(meta["identity"].get("mesh"), dict)):
            missing.append("a valid identity and step")
    if missing:
        raise CheckpointError(f"cannot read {path}: it is not a checkpoint of a run ({', '.join(missing)} missing)")


def resume(out, identity, fields, integ, nsteps, comm, history=None, allow_changed_source=False):
    """Restore ``fields``, the active set and the solver's history from ``out``'s checkpoint
    (collective). Checks everything before any file is touched (``allow_changed_source``: the
    problem file's hash and the package's version may differ, as the user allowed).

    Returns:
        (first step, run id, files) with files the checkpoint's record of the run's files
        (None for a checkpoint of an older version).

    Raises:
        CheckpointError: no checkpoint, a damaged one, one of another run, mesh or
            parameters, or a time series that does not reach it.
    """
    if out is None:
        raise CheckpointError("restart needs the output folder of the run")
    data, meta = checkpoint.load(out, comm)
    _check_complete(data, meta, Path(out) / checkpoint.CHECKPOINT)
    check_identity(meta["identity"], identity, allow_changed_source)
    if meta["step"] > nsteps:
        raise CheckpointError(f"the checkpoint is at step {meta['step']}, past T = {nsteps * identity['dt']}")
    previous = checkpoint.previous_run_id(out, comm)
    if meta.get("run_id") != previous:
        raise CheckpointError(
            f"{Path(out) / checkpoint.CHECKPOINT} was written by another run than the one in "
            f"{Path(out) / 'run.json'} (run_id {meta.get('run_id')} vs {previous})")
    checkpoint.check_series(out, meta["step"], comm)
    checkpoint.restore(data, fields, comm)
    integ.active = checkpoint.active_mask(data, integ.discretisation.cx)
    if history is not None:
        history.restore(data)
    return meta["step"], previous, meta.get("files")


def save(out, identity, step, dt, run_id, fields, integ, comm, files, history=None):
    """Write ``out/checkpoint.npz`` for the state after ``step`` and commit the run's files
    to it (collective): the checkpoint names the files' state (a new token), then their undo
    logs start again from it.

    Raises:
        RunFileError: it could not be written (the previous checkpoint stays valid).
    """
    token = comm.bcast(uuid.uuid4().hex if comm.rank == 0 else None, root=0)
    meta = {"identity": identity, "step": step, "t": step * dt, "run_id": run_id, "files": files.record(token)}
    extra = history.capture() if history is not None else None
    active_x = integ.discretisation.cx[:, integ.active].T
    path = Path(out) / checkpoint.CHECKPOINT
    agree(comm, checkpoint.save, out, comm, fields, active_x, meta, extra, path=path)
    files.commit(token)
