"""Regenerate data/paper/*.toml: the runs behind the paper's figures and tables as
configuration files, from the study that ``python -m sdm_dolfinx figures`` runs.

    .venv/bin/python scripts/gen_paper_configs.py           # rewrite data/paper/*.toml
    .venv/bin/python scripts/gen_paper_configs.py --check   # exit 1 if data/paper is out of date

One source of truth: ``sdm_dolfinx.paper.study.make_study`` defines the runs (the paper's mesh
diagonals, the consistent C of P1 velocities as in the paper's program, the write interval),
so ``membrane --config data/paper/X.toml`` computes exactly the run the report shows.
"""
import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "data" / "paper"


def expected():
    sys.path.insert(0, str(ROOT))
    from sdm_dolfinx.paper import study
    return study.paper_configurations()


def differences(files):
    """Names missing, stale or extra in data/paper."""
    have = {p.name: p.read_text() for p in DATA.glob("*.toml")}
    return sorted(n for n in set(have) | set(files) if have.get(n) != files.get(n))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="only check; exit 1 if out of date")
    args = ap.parse_args(argv)
    files = expected()
    diff = differences(files)
    if args.check:
        if diff:
            print(f"data/paper is out of date ({len(diff)} files: {', '.join(diff[:5])}...); "
                  "run .venv/bin/python scripts/gen_paper_configs.py", file=sys.stderr)
            return 1
        return 0
    DATA.mkdir(parents=True, exist_ok=True)
    for p in DATA.glob("*.toml"):
        if p.name not in files:
            p.unlink()
    for name, text in files.items():
        (DATA / name).write_text(text)
    print(f"data/paper: {len(files)} configurations ({len(diff)} changed)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
