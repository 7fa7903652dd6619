"""One benchmark record from fresh processes: a case run ``repeats`` times, each in a process of its own
(``mpirun -n ranks`` for several ranks), its record the median by the time of a contact step."""
import json
import subprocess
import sys


def median_of_fresh_runs(script, args, ranks, repeats=3, key="contact_step_s"):
    """Run ``python script *args`` ``repeats`` times (the last line of its stdout a JSON record); the
    median record by ``key``, with every run's ``key`` as ``repeats``."""
    records = []
    for _ in range(repeats):
        cmd = [sys.executable, str(script), *map(str, args)]
        if ranks > 1:
            cmd = ["mpirun", "-n", str(ranks), *cmd]
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        records.append(json.loads(out.strip().splitlines()[-1]))
    records.sort(key=lambda r: r[key] or 0.0)
    rec = records[len(records) // 2]
    rec["repeats"] = [r[key] for r in records]
    return rec
