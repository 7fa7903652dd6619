"""The command line's help: every command lists every option, docs/cli.md is current."""
import argparse
import contextlib
import io
import os
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI

import pytest

from sdm_dolfinx import cli

COMM = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parents[2]


def clean_env():
    """The environment without the MPI job's variables, so that a child process is a fresh singleton."""
    keep = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "OMPI_MCA_btl")
    return {k: v for k, v in os.environ.items()
            if k in keep or not k.startswith(("OMPI_", "PMIX_", "OPAL_", "PRTE_", "HYDRA_", "PMI_"))}


# ------------------------------------------------------------------------------- the command line
def _help_of(argv):
    """(help text, the parsers that printed it) of ``python -m sdm_dolfinx ARGV`` run in-process."""
    printed = []
    original = argparse.ArgumentParser.format_help

    def spy(parser):
        text = original(parser)
        printed.append((parser, text))
        return text
    out = io.StringIO()
    argparse.ArgumentParser.format_help = spy
    try:
        with contextlib.redirect_stdout(out):
            try:
                status = cli.main(argv)
            except SystemExit as e:
                status = e.code
    finally:
        argparse.ArgumentParser.format_help = original
    return status, out.getvalue(), printed


@pytest.mark.parametrize("command", [None] + cli.commands())
def test_help_lists_every_option(command):
    """``--help`` of the program and of every command exits 0 and lists each option (checked on rank 0,
    which is the rank that prints; the verdict is shared so that all ranks pass or fail together)."""
    argv = ["--help"] if command is None else [command, "--help"]
    status, text, printed = _help_of(argv)
    problem = None
    if COMM.rank == 0:
        if status not in (0, None):
            problem = f"{argv}: exit status {status}"
        elif not printed:
            problem = f"{argv}: no argparse help was printed"
        else:
            parser, help_text = printed[-1]
            missing = [s for a in parser._actions if a.help != argparse.SUPPRESS for s in a.option_strings
                       if s not in help_text]
            if help_text.strip() not in text:
                problem = f"{argv}: the help was not written to stdout"
            elif missing:
                problem = f"{' '.join(argv)} does not list {missing}"
            elif command is None:
                absent = [name for name in cli.commands() if name not in help_text]
                problem = f"--help does not name the commands {absent}" if absent else None
    problem = COMM.bcast(problem, root=0)
    assert problem is None, problem


def test_python_m_help_in_a_real_process():
    """``python -m sdm_dolfinx --help`` and ``membrane --help`` in a fresh process (rank 0)."""
    ok = True
    if COMM.rank == 0:
        for argv in (["--help"], ["membrane", "--help"], ["disc", "--help"]):
            p = subprocess.run([sys.executable, "-m", "sdm_dolfinx", *argv], capture_output=True, text=True,
                               env=clean_env(), cwd=ROOT, timeout=120)
            ok &= p.returncode == 0 and "usage:" in p.stdout and "Traceback" not in p.stderr
            if argv[0] == "membrane":
                ok &= all(o in p.stdout for o in ("--pair", "--dt", "--T", "--N", "--out", "--write-every"))
    assert COMM.bcast(ok, root=0)


def test_top_level_help_names_every_command():
    """``python -m sdm_dolfinx --help`` names every run command and every other command, each with its
    one-line description."""
    status, text, printed = _help_of(["--help"])
    problem = None
    if COMM.rank == 0:
        help_text = printed[-1][1]
        lines = {line.split()[0]: line for line in help_text.splitlines() if line.startswith("    ")}
        absent = [name for name in cli.commands()
                  if name not in lines or len(lines[name].split()) < 3]
        problem = f"--help does not name (with a description) {absent}" if absent else None
    problem = COMM.bcast(problem, root=0)
    assert problem is None, problem


@pytest.mark.skipif(COMM.size > 1, reason="runs every command's --help in child processes: serial only")
@pytest.mark.slow
def test_cli_reference_is_current():
    """docs/cli.md is exactly what scripts/gen_cli_doc.py makes from today's --help texts."""
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "gen_cli_doc.py"), "--check"], capture_output=True,
                       text=True, env=clean_env(), cwd=ROOT, timeout=300)
    assert p.returncode == 0, f"docs/cli.md is stale: run scripts/gen_cli_doc.py ({p.stdout}{p.stderr})"

