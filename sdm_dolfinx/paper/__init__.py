"""Reproduce the paper: every figure and table of Renard (2010), regenerated from the runs' files.

``python -m sdm_dolfinx figures [--quick] [--out DIR] [--runs DIR]`` (or ``make figures``;
the command line is :mod:`sdm_dolfinx.cli.figures`) runs the studies of the paper's
sections 4 and 5 through :func:`sdm_dolfinx.run.simulate` (each run keeps its
``timeseries.csv``, ``run.json``, ``state.h5`` in ``--runs``), then reads those files back
and writes, into ``--out``:

* one PNG per figure of the paper (Figs. 1-11, 13-16) plus Table 2, and 3-D pictures of
  the membrane on the obstacle and of the deformed disc;
* ``index.html``: each of our figures next to what the paper's figure shows and a
  sentence, computed from the runs' numbers, saying whether ours agrees;
* ``numbers.json``: every number quoted in the report.

A study is resumable: a run whose folder holds a finished (or deterministically failed)
run with the same parameters is not run again; an interrupted long run continues from its
checkpoint. ``--quick`` (coarser, shorter; a few minutes) is the smoke test.

Modules, in the order of the work: :mod:`.study` (the runs, the ``data/paper`` TOML files),
:mod:`.runs` (computing what is missing), :mod:`.metrics` (the numbers), :mod:`.figures`
and :mod:`.disc_figures` (the paper's figures, with :mod:`.plotting`), :mod:`.pictures`
(3-D pictures; pyvista in a child process, :mod:`.pyvista_scene`) and :mod:`.report`; the
friction section (issue 17, not in the paper): :mod:`.friction_study` (its runs),
:mod:`.friction` (the incline and the block) and :mod:`.friction_impact` (the oblique impact).
Post-processing reads HDF5 on rank 0 (h5py) and computes the disc's H¹ errors between
non-matching meshes in parallel (:mod:`sdm_dolfinx.post`); the runs use all ranks.
"""
