"""The method comparison, a user feature (``python -m sdm_dolfinx compare``): every class of
dynamic-contact method on one problem over a grid of h and dt, against its exact solution (or the
finest well-posed run), with figures and a ranking.

:mod:`.catalogue` names every method as a combination of run options; :mod:`.grid` runs one method
at one (h, dt) in its own folder, resumably; :mod:`.reference` measures field errors against a
reference run; :mod:`.comparison` lays out and runs the grid; :mod:`.table` (rates, ranking) and
:mod:`.figures` present it. The metrics themselves are :mod:`sdm_dolfinx.post.metrics`.
"""
