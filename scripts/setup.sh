#!/usr/bin/env bash
# Install what sdm_dolfinx needs on Debian 12: Debian packages (only the missing ones), then a
# .venv with --system-site-packages and the package in editable mode. Idempotent.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
PKGS="python3-dolfinx python3-petsc4py python3-mpi4py python3-h5py python3-matplotlib python3-pytest
python3-pytest-xdist python3-gmsh python3-scipy python3-venv python3-pip python3-setuptools openmpi-bin libopenblas0-serial"
# libopenblas0-serial: Debian's alternatives then give MUMPS OpenBLAS instead of the reference BLAS
# (3-D factorisations 1.7-4x faster, results equal to 1e-12: bench/README.md "BLAS").
missing=()
for p in $PKGS; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  echo "setup: installing Debian packages: ${missing[*]}"
  $SUDO apt-get update -qq
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv (system site packages: dolfinx, PETSc, MPI come from Debian)"
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
if ! (cd / && "$ROOT/.venv/bin/python" -c "import sdm_dolfinx") 2>/dev/null; then
  .venv/bin/python -m pip install -q --no-build-isolation --no-deps -e .
fi
.venv/bin/python -c "import dolfinx, sdm_dolfinx; print('setup: dolfinx', dolfinx.__version__, '- sdm_dolfinx', sdm_dolfinx.__version__)"
# mypy for `make typecheck`, which `make test` (CI) runs first: not optional, so a failure to
# install it fails the set-up. Pinned: a new mypy may find new errors in unchanged code.
MYPY_VERSION=2.4.1
if ! .venv/bin/python -m mypy --version 2>/dev/null | grep -q "^mypy $MYPY_VERSION "; then
  echo "setup: installing mypy $MYPY_VERSION into .venv (make typecheck)"
  .venv/bin/python -m pip install -q "mypy==$MYPY_VERSION"
fi
# Optional extras for pictures and animations (sdm_dolfinx/render.py): pyvista with its VTK wheel
# (renders off-screen through EGL/OSMesa, no display needed) and imageio. About 25 s and 600 MB
# once; a quick look-up when present. Numpy stays Debian's (dolfinx is built against it).
# SDM_NO_EXTRAS=1 skips them; a failure only warns (everything falls back to matplotlib).
if [ -z "${SDM_NO_EXTRAS:-}" ] && ! .venv/bin/python -c "import importlib.util as u, sys; sys.exit(not (u.find_spec('pyvista') and u.find_spec('imageio')))" 2>/dev/null; then
  echo "setup: installing the optional extras pyvista, imageio into .venv (SDM_NO_EXTRAS=1 skips)"
  NUMPY_PIN=$(.venv/bin/python -c "import numpy; print(numpy.__version__)")
  .venv/bin/python -m pip install -q pyvista imageio "numpy==$NUMPY_PIN" \
    || echo "setup: warning: pyvista could not be installed; pictures fall back to matplotlib"
fi
