"""The ``ftdrake`` command: the parser, assembled from each command module's ``register``."""

from __future__ import annotations

import argparse
import sys

from ..version import ftdrake_version
from . import (
    calibrate,
    evaluate,
    experiments,
    export,
    feedforward,
    hardware,
    replay,
    simulation,
    study,
    train,
)
from .args import HelpFormatter, run

# In the order ``ftdrake --help`` lists them: the rig, models, a live robot, the experiments.
COMMAND_MODULES = (simulation, train, evaluate, export, replay, calibrate, hardware, experiments,
                   study, feedforward)

DESCRIPTION = """\
Learned compensation of a wrist force/torque sensor on Drake: simulate the rig, collect data,
train and evaluate compensators, replay the runtime chain over a log, calibrate a sensor, run
on a live robot over LCM or ROS 2, and repeat the experiments. `ftdrake COMMAND --help`
shows a command's flags and their defaults."""


def build_parser() -> argparse.ArgumentParser:
    """The ``ftdrake`` parser with every command of :data:`COMMAND_MODULES`."""
    parser = argparse.ArgumentParser(prog="ftdrake", description=DESCRIPTION,
                                     formatter_class=HelpFormatter)
    parser.add_argument("--version", action="version", version=f"ftdrake {ftdrake_version()}")
    parser.add_argument("--verbose", action="store_true",
                        help="print every warning Drake's parser gives about a robot "
                             "description (by default one line sums them up)")
    sub = parser.add_subparsers(dest="command", required=True, title="commands",
                                metavar="COMMAND")
    for module in COMMAND_MODULES:
        module.register(sub)
    return parser


def main(argv=None) -> int:
    """Parses `argv` (default: ``sys.argv[1:]``) and runs the command: 0 on success, 2 for a
    problem the user can fix (one line on stderr naming the flag)."""
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
