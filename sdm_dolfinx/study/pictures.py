"""Pictures of stored states: render a 3-D scene with pyvista off screen in a child process
(:mod:`.pyvista_scene`; the caller falls back to matplotlib when it cannot), and pick the stored
state where a time-series column peaks. Rank 0 only: the states are read with the serial HDF5
reader."""
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np

from sdm_dolfinx import io as sdm_io
from sdm_dolfinx import post
from sdm_dolfinx.study.series import Series

#: the folder of the child process's module (put on its PYTHONPATH, see pyvista_scene)
_HERE = Path(__file__).resolve().parent


def _one_line(text):
    return " ".join(str(text).split())[:200]


def render_pyvista(kind, arrays, png, timeout=300):
    """Render with pyvista off screen in a child process; returns (ok, reason if not)."""
    if os.environ.get("SDM_NO_PYVISTA"):
        return False, "pyvista disabled by SDM_NO_PYVISTA"
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "scene.npz"
        np.savez(data, kind=kind, **arrays)
        env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_"))}
        env["PYTHONPATH"] = os.pathsep.join([str(_HERE)] + [p for p in [env.get("PYTHONPATH")] if p])
        try:
            p = subprocess.run([sys.executable, "-P", "-m", "pyvista_scene", str(data), str(Path(png).resolve())],
                               capture_output=True, text=True, timeout=timeout, env=env, cwd=tmp)
        except (OSError, subprocess.TimeoutExpired) as e:
            return False, f"pyvista could not run ({_one_line(e)})"
    if p.returncode == 0 and Path(png).exists():
        return True, ""
    err = [ln for ln in p.stderr.splitlines() if ln.strip() and "WARN" not in ln]
    if any("No module named 'pyvista'" in ln for ln in err):
        return False, "pyvista is not installed"
    return False, f"pyvista failed (status {p.returncode}: {_one_line(err[-1] if err else '')})"


def pick_state(series, reader, column, upto=None):
    """The stored row whose step maximises ``column`` (earliest on ties, optionally t <= upto)."""
    best, row = -np.inf, len(reader) - 1
    for i, step in enumerate(reader.steps):
        if upto is not None and reader.t[i] > upto:
            break
        v = series[column][int(step)]
        if v > best:
            best, row = v, i
    return row


def peak_state(folder):
    """The stored state of largest contact force of the run in ``folder`` (rank 0, COMM_SELF):
    (info, problem, W, u, t, force)."""
    s = Series(folder)
    info, problem, W, Vs = post.rebuild(folder, MPI.COMM_SELF)
    reader = sdm_io.StateReader(folder, W, Vs, MPI.COMM_SELF)
    row = pick_state(s, reader, "contact_force")
    u, _ = reader.read(row)
    return info, problem, W, u, float(reader.t[row]), float(s["contact_force"][int(reader.steps[row])])
