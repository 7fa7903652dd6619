#!/bin/bash
# The recorded benchmark (bench/results/*.json, bench/time_per_step.png), in order of priority.
# Extra arguments go to every bench/run.py call (e.g. --skip-done to continue).
set -x
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
$PY bench/run.py --suite disc --ranks 1 --strategies auto,schur,cg-factor,amg,cg-amg,lu,rsls "$@"
$PY bench/run.py --suite disc-window --ranks 1 --strategies auto,lu,rsls "$@"
$PY bench/run.py --suite disc --ranks 2 --strategies auto,lu "$@"
$PY bench/run.py --suite membrane --ranks 1 "$@"
$PY bench/run.py --suite membrane --ranks 2 --strategies auto,lu --sizes 20 40 80 160 320 "$@"
$PY bench/run.py --suite disc-level6 --ranks 1 2 --strategies auto --timeout 3600 "$@"
