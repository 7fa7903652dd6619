"""What differs between PETSc builds and petsc4py versions: which external packages PETSc was
configured with, and calls petsc4py 3.18 does not wrap. Imports nothing of ours."""
import ctypes
from typing import Any

from petsc4py import PETSc


def petsc_has(package: str) -> bool:
    """Whether this PETSc was configured with the external package ``package`` ("suitesparse" for
    CHOLMOD, "mumps", "hypre"; PETSc's lower-case configure names).

    Debian's PETSc (3.18, 3.22) has all three; the PyPI wheel dolfinx-solver-real (PETSc 3.25)
    has MUMPS but neither SuiteSparse nor hypre. The solvers ask here, and only here, so that a
    test can pretend a package is absent by replacing this one function.
    """
    return bool(PETSc.Sys.hasExternalPackage(package))


def pc_failed_reason(pc):
    """``PC.getFailedReason()`` (petsc4py >= 3.20), or 0 on older petsc4py: MUMPS reports
    its failures through INFOG(1) on every version."""
    return int(pc.getFailedReason()) if hasattr(pc, "getFailedReason") else 0


_options_used: list[Any] = []      # [PetscOptionsUsed wrapper or None], found on first use


def petsc_options_used(name):
    """Whether PETSc has read the option ``name`` (no dash); None where that cannot be asked.

    petsc4py (3.18 at least) does not wrap PetscOptionsUsed: it is called through ctypes in
    libpetsc, which petsc4py's extension links."""
    if not _options_used:
        try:
            f = ctypes.CDLL(PETSc.__file__).PetscOptionsUsed
            f.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
            f.restype = ctypes.c_int
        except (OSError, AttributeError):
            f = None
        _options_used.append(f)
    f = _options_used[0]
    if f is None:
        return None
    flag = ctypes.c_int(0)
    return f(None, name.encode(), ctypes.byref(flag)) == 0 and bool(flag.value)
