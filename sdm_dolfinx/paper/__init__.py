"""Renard (2010) reproduced: every figure and table of the paper, regenerated from the runs' files.

Modules, in the order of the work: :mod:`.design` (which runs reproduce each figure and table,
and the ``data/paper`` TOML files), :mod:`.membrane_figures` (section 4, Figs. 2-11) and
:mod:`.disc_figures` (section 5, Figs. 13-16), :mod:`.table2` (Table 2 as the paper's program
computed it and at t = 0.02 s exactly), :mod:`.numbers` (the counting condition of (7), the disc's
convergence rates, the energy recomputed from stored fields) and :mod:`.pictures_3d` (the
membrane on the obstacle, Fig. 1, and the deformed disc). The runs are computed and reused by
:mod:`sdm_dolfinx.study`; ``python -m sdm_dolfinx figures`` (:mod:`sdm_dolfinx.report`) puts these
next to the validation studies in one report. Post-processing reads HDF5 on rank 0 (h5py) and
computes the disc's H¹ errors between non-matching meshes in parallel; the runs use all ranks.
"""
