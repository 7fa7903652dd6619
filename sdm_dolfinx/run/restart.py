"""Continuing a run from its checkpoint, and writing checkpoints (see :mod:`.checkpoint`)."""
import sys
from pathlib import Path

from sdm_dolfinx.run import checkpoint
from sdm_dolfinx.run.checkpoint import CheckpointError

#: what must be the same for a checkpoint to continue a run
IDENTITY_KEYS = ("problem", "pair", "mass", "scheme", "dt", "vi_solver", "linear", "ranks")


def check_identity(saved, now):
    """A checkpoint continues only the run that wrote it."""
    for key in IDENTITY_KEYS:
        if saved.get(key) != now.get(key):
            raise CheckpointError(
                f"the checkpoint was written with {key} = {saved.get(key)!r}, this run has {now.get(key)!r}"
                + (" (restart on the same number of ranks)" if key == "ranks" else ""))
    if not checkpoint.same_fingerprint(saved["mesh"], now["mesh"]):
        raise CheckpointError("the checkpoint was written on a different mesh")


def resume(out, identity, fields, integ, nsteps, comm):
    """Restore ``fields`` and the active set from ``out``'s checkpoint (collective).

    Returns:
        (first step, run id, outputs) with outputs as of :func:`checkpoint.check_outputs`.

    Raises:
        CheckpointError: no checkpoint, or one of another run, mesh or parameters.
    """
    if out is None:
        raise CheckpointError("restart needs the output folder of the run")
    data, meta = checkpoint.load(out, comm)
    check_identity(meta["identity"], identity)
    if meta["step"] > nsteps:
        raise CheckpointError(f"the checkpoint is at step {meta['step']}, past T = {nsteps * identity['dt']}")
    previous = checkpoint.previous_run_id(out, comm)
    if meta.get("run_id") != previous:
        raise CheckpointError(
            f"{Path(out) / checkpoint.CHECKPOINT} was written by another run than the one in "
            f"{Path(out) / 'run.json'} (run_id {meta.get('run_id')} vs {previous})")
    outputs = checkpoint.check_outputs(out, meta["step"], comm)     # may move damaged files aside
    checkpoint.restore(data, fields, comm)
    integ.active = checkpoint.active_mask(data, integ.discretisation.cx)
    first = meta["step"]
    if outputs["moved"] and comm.rank == 0:
        print(f"warning: {', '.join(n.replace('.damaged', '') for n in outputs['moved'] if n.endswith('.h5'))} "
              f"could not be read (the run was killed while writing it): moved to "
              f"{', '.join(outputs['moved'])}; the fields continue from step {first} in new files",
              file=sys.stderr, flush=True)
    return first, previous, outputs


def save(out, identity, step, dt, run_id, fields, integ, comm):
    """Write ``out/checkpoint.npz`` for the state after ``step`` (collective)."""
    meta = {"identity": identity, "step": step, "t": step * dt, "run_id": run_id}
    checkpoint.save(out, comm, fields, integ.discretisation.cx[:, integ.active].T, meta)
