"""The command line starts without the library: ``ftdrake --version`` and ``ftdrake COMMAND
--help`` load neither Drake nor scikit-learn, pandas, numba, scipy or the compensators, and
parse only the command given. What is loaded is read from ``sys.modules`` of a fresh
interpreter (no timing here: ``benchmarks/import_time.py`` measures the time)."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ftdrake.cli.main import COMMANDS, SUMMARIES, build_parser, commands_named

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("pydrake", "sklearn", "pandas", "numba", "scipy", "matplotlib", "dask",
         "ftdrake.compensation", "ftdrake.sim", "ftdrake.systems", "ftdrake.experiments")

# Runs the command line's main on argv (JSON) in a fresh interpreter and prints its exit
# status and the modules then loaded.
_RUN = """
import json, sys
from ftdrake.cli.main import main
try:
    status = main(json.loads(sys.argv[1]))
except SystemExit as e:
    status = e.code
print(json.dumps({"status": status, "modules": sorted(sys.modules)}))
"""


def loaded_by(argv: list[str]) -> tuple[int, list[str], str]:
    path = os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])
    done = subprocess.run([sys.executable, "-c", _RUN, json.dumps(argv)], capture_output=True,
                          text=True, timeout=300, check=False, cwd=ROOT,
                          env={**os.environ, "PYTHONPATH": path})
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    return result["status"], result["modules"], done.stdout


def heavy(modules: list[str]) -> list[str]:
    return [m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY)]


# train, evaluate and calibrate offer the compensator registry's kinds and options as flags,
# and study the study's defaults, which their modules import: their --help loads them.
LIGHT_COMMANDS = ["serve", "record", "replay", "simulate", "collect", "export", "demo",
                  "evaluate-detection", "learn-feedforward", "export-correction"]


@pytest.mark.parametrize("argv", [["--version"], ["--verbose", "--version"],
                                  *([c, "--help"] for c in LIGHT_COMMANDS)])
def test_version_and_help_load_no_heavy_library(argv):
    status, modules, output = loaded_by(argv)
    assert status == 0
    assert not heavy(modules), heavy(modules)
    assert ("ftdrake " if argv[-1] == "--version" else f"usage: ftdrake {argv[0]}") in output


@pytest.mark.parametrize("argv", [["--help"], ["--verbose", "--help"], [], ["serv"]])
def test_the_overview_imports_no_command_module(argv):
    """``ftdrake --help`` (and no command, or a misspelt one) lists every command without
    importing a command module: no library a command runs is loaded, whichever command."""
    status, modules, output = loaded_by(argv)
    assert status == (0 if "--help" in argv else 2)
    assert not heavy(modules), heavy(modules)
    commands = {f"ftdrake.cli.{m}" for m in COMMANDS.values()}
    assert not commands & set(modules), sorted(commands & set(modules))
    if status == 0:
        assert "usage: ftdrake" in output
        assert all(f"    {c}" in output and SUMMARIES[c] in " ".join(output.split())
                   for c in COMMANDS)


def test_the_overview_lists_each_command_by_the_line_its_module_registers():
    """:data:`SUMMARIES` (the overview's lines) is what each command module registers as its
    help, and the overview lists the commands in :data:`COMMANDS`' order."""
    def lines(parser):
        sub = next(x for x in parser._actions if isinstance(x, argparse._SubParsersAction))
        return [(a.dest, a.help) for a in sub._choices_actions]

    assert lines(build_parser(overview=True)) == lines(build_parser())
    assert list(SUMMARIES) == list(COMMANDS)


def test_a_command_that_runs_loads_what_it_needs():
    """The check above would pass on a command line that imports nothing at all: ``export``
    with a file that is not a model gets as far as reading it, with the library."""
    status, modules, _ = loaded_by(["export", "--model", __file__, "--out", "x.onnx"])
    assert status == 2  # the model file is refused, naming --model
    assert "ftdrake.compensation.files.persistence" in modules


def test_each_module_registers_the_commands_the_table_gives_it():
    """:data:`COMMANDS` (command → module) is how main finds a command's module: each module
    registers exactly the commands the table maps to it, and every command is in the table."""
    for module in set(COMMANDS.values()):
        expected = {c for c, m in COMMANDS.items() if m == module}
        sub = next(x for x in build_parser(sorted(expected))._actions
                   if isinstance(x, argparse._SubParsersAction))
        assert set(sub.choices) == expected, module
    sub = next(x for x in build_parser()._actions if isinstance(x, argparse._SubParsersAction))
    assert list(sub.choices) == list(COMMANDS)


@pytest.mark.parametrize("argv, expected", [
    (["serve", "--help"], ["serve"]),
    (["--verbose", "replay", "--model", "m.ftd"], ["replay"]),
    (["--version"], []),
    (["--version", "--help"], None),
    (["--help"], None),
    ([], None),
    (["serv"], None),  # misspelt: argparse names every command
])
def test_commands_named(argv, expected):
    assert commands_named(argv) == expected


def test_a_misspelt_command_is_refused_naming_every_command(capsys):
    from ftdrake.cli.main import main

    with pytest.raises(SystemExit) as exit_:
        main(["serv"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'serv'" in err
    assert all(c in err for c in COMMANDS)
