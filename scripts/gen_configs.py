"""Regenerate data/paper/*.toml and data/validation/*.toml: the runs behind the report's figures
and tables as configuration files, from the studies that ``python -m sdm_dolfinx figures`` runs.

    .venv/bin/python scripts/gen_configs.py           # rewrite both folders
    .venv/bin/python scripts/gen_configs.py --check   # exit 1 if one is out of date

One source of truth: the studies define the runs (``sdm_dolfinx.paper.design.make_study``: the
paper's mesh diagonals, the consistent C of P1 velocities as in the paper's program, the write
interval; ``sdm_dolfinx.validation.friction_study.friction_runs``), so ``membrane --config
data/paper/X.toml`` computes exactly the run the report shows.
"""
import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: folder -> the function (module, name) that gives its files
FOLDERS = {"paper": ("sdm_dolfinx.paper.design", "paper_configurations"),
           "validation": ("sdm_dolfinx.validation.friction_study", "configurations")}


def expected(folder):
    """File name -> text of ``data/<folder>``."""
    sys.path.insert(0, str(ROOT))
    import importlib
    module, name = FOLDERS[folder]
    return getattr(importlib.import_module(module), name)()


def differences(folder, files):
    """Names missing, stale or extra in ``data/<folder>``."""
    have = {p.name: p.read_text() for p in (ROOT / "data" / folder).glob("*.toml")}
    return sorted(n for n in set(have) | set(files) if have.get(n) != files.get(n))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="only check; exit 1 if out of date")
    args = ap.parse_args(argv)
    status = 0
    for folder in FOLDERS:
        files = expected(folder)
        diff = differences(folder, files)
        data = ROOT / "data" / folder
        if args.check:
            if diff:
                print(f"data/{folder} is out of date ({len(diff)} files: {', '.join(diff[:5])}...); "
                      "run .venv/bin/python scripts/gen_configs.py", file=sys.stderr)
                status = 1
            continue
        data.mkdir(parents=True, exist_ok=True)
        for p in data.glob("*.toml"):
            if p.name not in files:
                p.unlink()
        for name, text in files.items():
            (data / name).write_text(text)
        print(f"data/{folder}: {len(files)} configurations ({len(diff)} changed)")
    return status


if __name__ == "__main__":
    sys.exit(main())
