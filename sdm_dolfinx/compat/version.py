"""The dolfinx version, the one place it is read (the rest of :mod:`sdm_dolfinx.compat` branches on it)."""
import dolfinx

DOLFINX_VERSION = tuple(int(p) for p in dolfinx.__version__.split(".")[:2])
#: dolfinx >= 0.7: basix.ufl elements, ``functionspace``, ``x.petsc_vec``, ``bb_tree`` ...
NEW_API = DOLFINX_VERSION >= (0, 7)
