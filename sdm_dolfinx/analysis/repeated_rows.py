"""Rows of a constraint matrix G that repeat each other: the same constraint written twice (the two passes
of a node-to-surface contact where the faces' vertices meet). Condition (7) asks G to be surjective, which
repeated rows are not although the constraint set {G U >= g} is the same without them: the inspector
measures it on the distinct rows and counts the others (:func:`~sdm_dolfinx.analysis.infsup.measure`)."""
import numpy as np

#: two rows of G whose unit vectors are this close (max norm) are the same constraint
REPEAT_TOL = 1e-9


def distinct_rows(G):
    """The indices (sorted) of the first of each group of rows of the sparse G that repeat each other: the
    same unit vector to :data:`REPEAT_TOL` (the same constraint written twice; a row and its negative
    are not: they are two bounds)."""
    import scipy.sparse as sp
    G = sp.csr_matrix(G)
    G.sort_indices()
    norms = np.sqrt(np.asarray(G.multiply(G).sum(axis=1)).ravel())
    keys: dict = {}
    keep = []
    for i in range(G.shape[0]):
        lo, hi = G.indptr[i], G.indptr[i + 1]
        cols, vals = G.indices[lo:hi], G.data[lo:hi] / max(norms[i], 1e-300)
        big = np.abs(vals) > REPEAT_TOL
        cols, vals = cols[big], vals[big]
        key = tuple(cols.tolist())
        same = keys.setdefault(key, [])
        if any(np.max(np.abs(vals - v), initial=0.0) <= REPEAT_TOL for v in same):
            continue
        same.append(vals)
        keep.append(i)
    return np.asarray(keep, dtype=np.int64)
