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

#: Each command → its one line in ``ftdrake --help``, the `help` its module registers (a test
#: keeps the two equal): the overview lists the commands without importing their modules,
#: some of which load the compensator registry to offer its kinds as flags.
SUMMARIES = {
    "simulate": "run the diagram once: log, figure, summary",
    "collect": "free-motion runs → one Parquet dataset",
    "train": "fit a compensator on a robot log; save it",
    "evaluate": "score a saved compensator on a robot log",
    "export": "a saved compensator → ONNX",
    "replay": "the runtime chain run offline over a log",
    "calibrate": "identify payload, biases, mounting, drift",
    "serve": "run a compensator on a live robot (LCM or ROS 2)",
    "record": "record a live robot (LCM or ROS 2) for train/evaluate",
    "demo": "collect → train → contact scenario in the loop",
    "evaluate-detection": "contact detection of models on unseen seeds",
    "study": "RF vs SVR (+ physics, hybrid): the study repeated",
    "learn-feedforward": "learn the torque feedforward (GP), ILC beside it",
    "results": "list or regenerate the results pages' files",
    "export-correction": "export a two-part model's joint reference correction along a path (CSV)",
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


def build_parser(commands=None, overview: bool = False) -> argparse.ArgumentParser:
    """The ``ftdrake`` parser with the commands `commands` (default: every command of
    :data:`COMMANDS`). With `overview`, every command is listed by its line of
    :data:`SUMMARIES` and no command module is imported (``ftdrake --help``, no command or a
    misspelt one: the parser only lists the commands); `commands` is then ignored."""
    parser = Parser(prog="ftdrake", description=DESCRIPTION, formatter_class=HelpFormatter)
    parser.add_argument("--version", action="version", version=f"ftdrake {ftdrake_version()}")
    parser.add_argument("--verbose", action="store_true",
                        help="print every warning Drake's parser gives about a robot "
                             "description (by default one line sums them up)")
    sub = parser.add_subparsers(dest="command", required=True, title="commands",
                                metavar="COMMAND")
    if overview:
        for name, line in SUMMARIES.items():
            sub.add_parser(name, help=line)
        return parser
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
    commands = commands_named(argv)
    return run(build_parser(commands, overview=commands is None).parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
