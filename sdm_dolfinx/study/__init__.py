"""The resumable-study toolkit the paper, the comparison and the validation studies share.

A study is a list of runs (:class:`.run_spec.Run`: a problem, its parameters, run options; written
as a TOML file by :func:`.run_spec.config_text`); :mod:`.runs` computes only what is missing or out
of date (an interrupted run continues from its checkpoint); :mod:`.series` reads a run's time series
back and compares two; :mod:`.entry` is one report entry with its verdict (a value, never parsed
out of a sentence) and :mod:`.text` puts numbers into sentences and tables; :mod:`.plotting` and
:mod:`.pictures` (pyvista in a child process, :mod:`.pyvista_scene`) draw.
"""
