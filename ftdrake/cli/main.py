"""The ``ftdrake`` command: the parser, assembled from each command module's ``register``.

Only the module of the command given is imported (:data:`COMMANDS`), and a command module
imports the library it runs inside its run function: ``ftdrake --version`` and
``ftdrake COMMAND --help`` load neither Drake nor scikit-learn, pandas or numba.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ..version import ftdrake_version
from .args import HelpFormatter, Parser, run

#: Each command → the module of ``ftdrake.cli`` that registers and runs it, in the order
#: ``ftdrake --help`` lists them: the rig, models, a live robot, the experiments.
COMMANDS = {
    "simulate": "simulation",
    "collect": "simulation",
    "train": "train",
    "evaluate": "evaluate",
    "export": "export",
    "replay": "replay",
    "calibrate": "calibrate",
    "serve": "hardware",
    "record": "hardware",
    "demo": "experiments",
    "evaluate-detection": "experiments",
    "study": "study",
    "learn-feedforward": "feedforward",
    "results": "results",
    "export-correction": "correction",
}

DESCRIPTION = """\
Learned compensation of a wrist force/torque sensor on Drake: simulate the rig, collect data,
train and evaluate compensators, replay the runtime chain over a log, calibrate a sensor, run
on a live robot over LCM or ROS 2, and repeat the experiments. `ftdrake COMMAND --help`
shows a command's flags and their defaults."""


def command_modules(commands=None) -> list:
    """The command modules (imported) that register `commands` (default: every command), in
    :data:`COMMANDS`' order."""
    names = dict.fromkeys(COMMANDS[c] for c in (COMMANDS if commands is None else commands))
    return [importlib.import_module(f".{name}", __package__) for name in names]


def build_parser(commands=None) -> argparse.ArgumentParser:
    """The ``ftdrake`` parser with the commands `commands` (default: every command of
    :data:`COMMANDS`)."""
    parser = Parser(prog="ftdrake", description=DESCRIPTION,
                                     formatter_class=HelpFormatter)
    parser.add_argument("--version", action="version", version=f"ftdrake {ftdrake_version()}")
    parser.add_argument("--verbose", action="store_true",
                        help="print every warning Drake's parser gives about a robot "
                             "description (by default one line sums them up)")
    sub = parser.add_subparsers(dest="command", required=True, title="commands",
                                metavar="COMMAND")
    for module in command_modules(commands):
        module.register(sub)
    return parser


def commands_named(argv: list[str]) -> list[str] | None:
    """The commands the parser needs for `argv`: the one it names (its first word that is not
    an option; the top-level options take no value), none for ``--version`` alone, else all
    of them (``--help``, no command, a misspelt one: argparse lists them)."""
    words = [w for w in argv if not w.startswith("-")]
    if words:
        return [words[0]] if words[0] in COMMANDS else None
    if "--version" in argv and not {"-h", "--help"} & set(argv):
        return []
    return None


def main(argv=None) -> int:
    """Parses `argv` (default: ``sys.argv[1:]``) and runs the command: 0 on success, 2 for a
    problem the user can fix (one line on stderr naming the flag)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    return run(build_parser(commands_named(argv)).parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
