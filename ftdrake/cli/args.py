"""The command line's shared grammar: argument types, the flags every command spells alike, the
help format, the deprecated-spelling action, and the run-time helpers that name a flag in
every error.

One spelling per concept, in every command that takes it:

==========================  =====================================================
``--config FILE``           the scenario YAML (default: the shipped one)
``--trajectory KIND``       a trajectory kind, from the library's list of kinds
``--kind KIND``             a compensator kind, from the compensator registry
``--model FILE``            a saved model file (``train --out``)
``--cluster ADDRESS``       a Dask scheduler, ``[PROTOCOL://]HOST:PORT``
``--jobs N``                local worker processes: N >= 1, or -1 for all cores
``--seed N``                a random seed in [0, 2**32)
``--html/--no-html``        write the Meshcat replay (replay.html) or not
``--quiet``                 no progress or status output on stderr
``--out PATH``              the output folder or file, checked before the run
==========================  =====================================================

Bad values are refused while parsing, before anything runs, as argparse refuses them:
``ftdrake CMD: error: argument --FLAG: REQUIREMENT; got VALUE`` and exit code 2. A spelling
replaced by one of these keeps working for one release through :class:`DeprecatedSpelling`,
which prints on stderr the spelling that replaces it.

A problem found while running (a field of the scenario, a model file) is a
:class:`~ftdrake.errors.FtdrakeError`; :func:`run` prints it as one line naming the flag that
set it, ``ftdrake CMD: error: --FLAG VALUE: MESSAGE``, and exits with 2. Any other exception
is a bug in ftdrake and keeps its traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import re
import shlex
import sys
import warnings
from pathlib import Path

from ..config import (
    TRAJECTORY_KINDS,
    RobotConfig,
    ScenarioConfig,
    load_chain_config,
    load_config,
)
from ..errors import ConfigError, FtdrakeError, command_line_front_end


# -- argument types -----------------------------------------------------------------------------
# Each takes the flag's text and returns its value, or raises ArgumentTypeError with the
# requirement; argparse prefixes the flag: "argument --duration: must be a positive number".
def number(parse, accept, requirement: str):
    """An argument type: `parse` (int or float) of the text, refused unless `accept(value)`;
    the refusal states `requirement` (the allowed range) and the text given."""

    def convert(text: str):
        try:
            value = parse(text)
        except ValueError:
            value = None
        if value is None or not accept(value):
            raise argparse.ArgumentTypeError(f"{requirement}; got {text!r}")
        return value

    return convert


positive_int = number(int, lambda v: v >= 1, "must be a whole number >= 1")
non_negative_int = number(int, lambda v: v >= 0, "must be a whole number >= 0")
positive_float = number(float, lambda v: 0 < v < math.inf, "must be a positive number")
finite_float = number(float, math.isfinite, "must be a finite number")
holdout_share = number(float, lambda v: 0 < v < 0.5,
                       "must be a share of the rows in (0, 0.5), e.g. 0.2")
seed = number(int, lambda v: 0 <= v < 2**32, "must be a whole number in [0, 2**32)")
jobs = number(int, lambda v: v >= 1 or v == -1,
              "must be a number of processes >= 1, or -1 for all cores")


def noise_values(text: str) -> list[float]:
    """An argument type: positive numbers ``S`` or ``S,S,...`` (noise std per target)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive numbers S or S,S,...; got "
                                         f"{text!r}")
    return values


def existing_file(text: str) -> Path:
    """An argument type: the path of a file that exists."""
    path = Path(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(
            f"{text}: {'a folder, not a file' if path.is_dir() else 'no such file'}")
    return path


def existing_path(text: str) -> Path:
    """An argument type: the path of a file or folder that exists (a ROS 2 bag is a folder)."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text}: no such file or folder")
    return path


def _writable(text: str, *, folder: bool) -> Path:
    """`text` as a path that can be written: a folder (`folder`) or a file, below a folder
    (created as needed)."""
    path = Path(text)
    if path.exists() and path.is_dir() != folder:
        raise argparse.ArgumentTypeError(
            f"{text}: is a {'file' if folder else 'folder'}; "
            f"give a {'folder' if folder else 'file'} name")
    parent = path.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: {parent} is a file, not a folder")
    return path


def output_folder(text: str) -> Path:
    """An argument type: a folder to write into (it may exist; it must not be a file)."""
    return _writable(text, folder=True)


def output_file(text: str) -> Path:
    """An argument type: a file to write (it may exist; it must not be a folder)."""
    return _writable(text, folder=False)


_ADDRESS = re.compile(r"((tcp|tls|ucx|ws|wss)://)?(\[[0-9A-Fa-f:.]+\]|[^\s:/\[\]]+):(\d+)")


def cluster_address(text: str) -> str:
    """An argument type: a Dask scheduler address ``[PROTOCOL://]HOST:PORT``, as
    ``dask.distributed.Client`` takes it (a TCP address needs its port)."""
    found = _ADDRESS.fullmatch(text)
    if found is None or not 0 < int(found.group(4)) < 65536:
        raise argparse.ArgumentTypeError(
            "must be a Dask scheduler address [PROTOCOL://]HOST:PORT, e.g. tcp://10.0.0.5:8786 "
            f"(PROTOCOL: tcp, tls, ucx, ws, wss; PORT 1..65535); got {text!r}")
    return text


# -- the flags every command spells alike --------------------------------------------------------
def add_config(p, help: str = "scenario YAML (default: the shipped one)"):
    return p.add_argument("--config", type=existing_file, metavar="FILE", help=help)


def add_chain_config(p):
    """``--config FILE``: the chain config (and ``--robot``, ``--sensor-frame``,
    ``--base-frame``: the robot joint-state gravity runs on) of a command that runs the chain
    on a live robot or a log."""
    p.add_argument("--config", type=existing_file, metavar="FILE",
                   help="chain config YAML: compensator, bias_tracker, detector, sensor "
                        "(rate, noise, drift, wrench_delay_s), robot at its top, or a live "
                        "config with chain:, lcm:, ros2: sections (default: the defaults; a "
                        "scenario file's chain is read too, with a warning)")
    p.add_argument("--robot", type=existing_file, metavar="FILE",
                   help="URDF/SDF of the robot joint-state gravity runs on, with "
                        "--sensor-frame (default: chain.robot, else the robot embedded in the "
                        "model)")
    p.add_argument("--sensor-frame", metavar="NAME",
                   help="frame S of the wrench in --robot")
    p.add_argument("--base-frame", metavar="NAME",
                   help="frame of --robot welded to the world (default: its root)")


def load_chain(args):
    """The ChainConfig of --config (validated where it is read) with --robot/--sensor-frame/
    --base-frame applied; errors name the flag."""
    with naming("--config", args.config) if args.config else contextlib.nullcontext():
        config = load_chain_config(args.config)
    return with_robot_flags(config, args)


def with_robot_flags(config, args):
    """`config` (a ChainConfig) with the robot --robot/--sensor-frame/--base-frame give."""
    if args.robot is None and args.sensor_frame is None and args.base_frame is None:
        return config
    if args.robot is None:
        raise ConfigError("--sensor-frame/--base-frame name frames of --robot FILE; give it")
    if not args.sensor_frame:
        raise ConfigError(f"--robot {args.robot} needs --sensor-frame NAME (the frame the "
                          "wrench is measured in)")
    config.robot = RobotConfig(file=str(args.robot), sensor_frame=args.sensor_frame,
                               base_frame=args.base_frame or "")
    return config


def add_trajectory(p, *, default: str, kinds=TRAJECTORY_KINDS, help: str = "trajectory kind"):
    """``--trajectory KIND``, one of `kinds` (a list the library keeps)."""
    return p.add_argument("--trajectory", choices=kinds, default=default, help=help)


def add_cluster(p, help: str):
    return p.add_argument("--cluster", type=cluster_address, metavar="ADDRESS", help=help)


def add_jobs(p, help: str = "local worker processes (-1: all cores)"):
    return p.add_argument("--jobs", type=jobs, default=-1, metavar="N", help=help)


def add_seed(p, default: int | None, help: str):
    return p.add_argument("--seed", type=seed, default=default, metavar="N", help=help)


def add_html(p, *, default: bool):
    """``--html/--no-html``: the Meshcat replay, replay.html."""
    return p.add_argument("--html", action=argparse.BooleanOptionalAction, default=default,
                          help="write replay.html, a Meshcat replay of the run")


def add_stream_delay(p, *, corrected: str, estimated: str) -> None:
    """``--delay S`` or ``--align``: the wrench stream's delay behind the joint states, given
    (s; negative: ahead) or estimated from the log. `corrected`/`estimated` say what the
    command does with it."""
    delay = p.add_mutually_exclusive_group()
    delay.add_argument("--delay", type=finite_float, metavar="S",
                       help="the wrench stream's delay behind the joint states (s; negative: "
                            f"ahead): {corrected}")
    delay.add_argument("--align", action="store_true",
                       help=f"estimate that delay ({estimated}), report it and correct it")


def add_joint_mapping(p) -> None:
    """--joints and --fixed-joints: a robot description with more joints than the log."""
    p.add_argument("--joints", metavar="NAME,NAME,..|FILE",
                   help="the joints of --robot the log's position columns hold, in their order "
                        "(when --robot has more: a torso, a head, fingers), or a YAML file of "
                        "'joints: [...]' and 'fixed_joints: {NAME: VALUE}' (default: all of "
                        "them, in the model's order)")
    p.add_argument("--fixed-joints", metavar="NAME=V,..|FILE",
                   help="where the joints of --robot not in --joints stand (rad, or m for "
                        "prismatic), or a YAML file mapping name to value (default: 0)")


def add_quiet(p, help: str = "no progress output"):
    return p.add_argument("--quiet", action="store_true", help=help)


def add_model_file(p, help: str = "a model file (train's --out)", **kwargs):
    return p.add_argument("--model", type=existing_file, metavar="FILE", help=help, **kwargs)


# -- old spellings --------------------------------------------------------------------------------
class DeprecatedSpelling(argparse.Action):
    """An old spelling of a flag, kept for one release: it sets what the new spelling sets
    (`values` maps an old value to the new one) and prints on stderr the spelling to use
    instead. Hidden from ``--help``."""

    def __init__(self, option_strings, dest, *, new: str, values: dict | None = None,
                 **kwargs):
        super().__init__(option_strings, dest, help=argparse.SUPPRESS, **kwargs)
        self.new, self.values = new, values

    def __call__(self, parser, namespace, values, option_string=None):
        value = self.const if self.nargs == 0 else values
        if self.values is not None:
            value = self.values[value]
        setattr(namespace, self.dest, value)
        instead = self.new if self.nargs == 0 else f"{self.new} {value}"
        given = option_string if self.nargs == 0 else f"{option_string} {values}"
        print(f"{parser.prog}: warning: {given} is deprecated and will be removed in the next "
              f"release; use {instead}", file=sys.stderr, flush=True)


def add_deprecated(p, old: str, new: argparse.Action, *, values: dict | None = None) -> None:
    """Adds `old` as a deprecated spelling of the argument `new` (what ``add_argument``
    returned): same destination and checks; `values` maps old values to new ones (its keys
    are the old spelling's choices). A flag without a value (``store_true``, ``--html``) sets
    True. ``--help`` shows only the new spelling; using the old one prints which replaces it.
    A required `new` is satisfied by either spelling (:class:`Parser` checks it)."""
    if new.required:
        new.required, new.needed_as = False, (*new.option_strings, old)
    if new.nargs == 0:
        p.add_argument(old, action=DeprecatedSpelling, new=new.option_strings[0],
                       dest=new.dest, nargs=0, const=True)
        return
    p.add_argument(old, action=DeprecatedSpelling, new=new.option_strings[0], dest=new.dest,
                   values=values, type=None if values else new.type,
                   choices=list(values) if values else new.choices, metavar=new.metavar)


# -- help --------------------------------------------------------------------------------------
class HelpFormatter(argparse.HelpFormatter):
    """One style for every command: an option's default after its help, ``(default: X)``,
    unless the help already says it or there is none to show (None; a flag without a value,
    but for ``--x/--no-x``); an option's choices as its value, ``--flag A|B|C``, or when they
    are too many to fit a line, ``--flag NAME`` and ``(NAME: A | B | C)`` in its help."""

    #: The longest ``A|B|C`` shown as an option's value (characters).
    CHOICES_WIDTH = 36

    @classmethod
    def choices_of(cls, action) -> str | None:
        """``A|B|C`` for an option with choices (None without)."""
        if action.metavar is not None or action.choices is None or not action.option_strings:
            return None
        return "|".join(str(choice) for choice in action.choices)

    def _metavar_formatter(self, action, default_metavar):
        choices = self.choices_of(action)
        if choices is not None:
            text = choices if len(choices) <= self.CHOICES_WIDTH else action.dest.upper()
            return lambda size: (text,) * size
        return super()._metavar_formatter(action, default_metavar)

    def _get_help_string(self, action):
        text = action.help or ""
        choices = self.choices_of(action)
        if choices is not None and len(choices) > self.CHOICES_WIDTH:
            note = f"({action.dest.upper()}: {choices.replace('|', ' | ')})"
            given = text.rfind(" (default: ")  # a default the help spells stays last
            if given >= 0 and text.endswith(")"):
                text = f"{text[:given]} {note}{text[given:]}"
            else:
                text = f"{text} {note}".lstrip()
        default = action.default
        if isinstance(action, argparse.BooleanOptionalAction) and default is not None:
            return f"{text} (default: {action.option_strings[0 if default else 1]})"
        if (not action.option_strings or action.nargs == 0 or "(default" in text
                or default is None or default is argparse.SUPPRESS):
            return text
        return f"{text} (default: %(default)s)"


_REQUIRED = "the following arguments are required: "


class Parser(argparse.ArgumentParser):
    """argparse's parser with errors a user reads at a glance: the command's short usage
    (``usage: ftdrake train --data FILE --out MODEL [OPTIONS]``), then the error; an unknown
    flag is reported by the command it was given to, with that command's usage."""

    def short_usage(self) -> str:
        """``usage: PROG``, its required options, ``[OPTIONS]`` for the others, then its
        positional arguments (``COMMAND ...`` for a parser of commands)."""
        required, positional, optional = [], [], False
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                positional.append(f"{action.metavar or 'COMMAND'} ...")
            elif not action.option_strings:
                positional.append(action.metavar or action.dest.upper())
            elif action.required or getattr(action, "needed_as", None):
                value = "" if action.nargs == 0 else f" {action.metavar or action.dest.upper()}"
                required.append(action.option_strings[0] + value)
            elif action.help is not argparse.SUPPRESS:
                optional = True
        return " ".join(["usage:", self.prog, *required, *(["[OPTIONS]"] if optional else []),
                         *positional])

    def error(self, message):
        missing = [flag for flag in self._missing() if flag not in message]
        if missing and message.startswith(_REQUIRED):
            message = f"{message}, {', '.join(missing)}"
        self.exit(2, f"{self.short_usage()}\n{self.prog}: error: {message}\n")

    def _missing(self) -> list[str]:
        """The required options with an old spelling (argparse does not see those given by
        it) that the arguments being parsed do not give."""
        given = {word.split("=", 1)[0] for word in getattr(self, "_argv", [])}
        return [action.option_strings[0] for action in self._actions
                if getattr(action, "needed_as", None) and not given & set(action.needed_as)]

    def parse_known_args(self, args=None, namespace=None):
        self._argv = list(sys.argv[1:] if args is None else args)
        parsed, extras = super().parse_known_args(args, namespace)
        missing = self._missing()
        if missing:
            self.error(f"{_REQUIRED}{', '.join(missing)}")
        return parsed, extras

    def parse_args(self, args=None, namespace=None):
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            self._parser_of(parsed, extras).error(f"unrecognized arguments: {' '.join(extras)}")
        return parsed

    def _parser_of(self, parsed, extras) -> argparse.ArgumentParser:
        """The parser of the command `parsed` ran if `extras` came after its name, else
        self."""
        argv = self._argv
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                name = getattr(parsed, action.dest, None)
                if name in argv and argv.index(extras[0]) > argv.index(name):
                    return action.choices[name]
        return self


def add_command(subparsers, name: str, help: str, description: str = ""):
    """A command's parser: `help` is its one line in ``ftdrake --help`` and opens its own
    ``--help``, followed by `description`; option defaults are shown."""
    return subparsers.add_parser(name, help=help, description=f"{help}. {description}".strip(),
                                 formatter_class=HelpFormatter)


# -- run time: loading what a flag names -------------------------------------------------------
@contextlib.contextmanager
def naming(flag: str, value):
    """Prefixes the message of a FtdrakeError raised inside with the flag that set `value`, so
    ``x.yaml: sensor.rate_hz ...`` reads ``--config x.yaml: sensor.rate_hz ...``."""
    try:
        yield
    except FtdrakeError as e:
        message = str(e)
        for prefix in (f"{value}: ", f"{value} "):
            message = message.removeprefix(prefix)
        raise type(e)(f"{flag} {value}: {message}") from None


def load_scenario(args) -> ScenarioConfig:
    """The scenario of --config (the shipped one without it); errors name --config."""
    if args.config is None:
        return load_config(None)
    with naming("--config", args.config):
        return load_config(args.config)


def scenario_from_args(args, kind: str | None = None) -> ScenarioConfig:
    """Loads --config and applies the trajectory `kind` and the --duration/--seed overrides
    common to commands."""
    config = load_scenario(args)
    if kind is not None:
        config.trajectory.kind = kind
    if getattr(args, "duration", None) is not None:
        config.trajectory.duration_s = args.duration
    if getattr(args, "seed", None) is not None:
        config.trajectory.seed = args.seed
        config.sensor.seed = args.seed
    return config.validate()


def run(args) -> int:
    """Runs a parsed command. A :class:`FtdrakeError` (a problem the user can fix: its message
    names the flag or field) prints as ``ftdrake CMD: error: MESSAGE`` and exits with 2, like
    argparse's own errors. Any other exception is a bug in ftdrake and keeps its traceback."""
    from ..data.logs import option_spelling
    from ..physics.robot import show_parser_warnings

    with (command_line_front_end(), option_spelling(flag_hint), one_line_warnings(),
          show_parser_warnings(getattr(args, "verbose", False))):
        try:
            return args.run(args) or 0
        except FtdrakeError as e:
            print(f"ftdrake {args.command}: error: {_naming_the_flag(e, args)}",
                  file=sys.stderr)
            return 2


def flag_hint(option: str, value) -> str:
    """How a message tells a command-line user to set reader option `option` (a
    :class:`~ftdrake.data.training.ReadOptions` field, ``sg_polyorder``) to `value`: the
    flag (``--sg-polyorder 3``), quoted for the shell where needed (``--positions 'q_*'``)."""
    flag = "--" + option.replace("_", "-")
    if option == "check_units":
        return "--no-check-units" if value is False else "omit --no-check-units"
    if value is None and option in ("velocities", "accelerations"):
        return f"{flag} derive"  # computed from q; also overrides a model's manifest
    if value is None:
        return f"omit {flag}"
    return f"{flag} {shlex.quote(str(value))}"


@contextlib.contextmanager
def one_line_warnings():
    """Within the block, a warning of ftdrake's prints as one line on stderr,
    ``warning: MESSAGE``, without the Python source line a user cannot act on; other
    packages' warnings print as Python prints them."""
    original = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if category.__module__.split(".")[0] == "ftdrake":
            print(f"warning: {message}", file=sys.stderr, flush=True)
        else:
            original(message, category, filename, lineno, file, line)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = original


# Scenario fields that a command's flag sets (`--duration` overrides the file's duration_s).
_FIELD_FLAGS = {"trajectory.duration_s": "--duration"}


def _naming_the_flag(error: FtdrakeError, args) -> str:
    """The message of `error`, reworded to name the flag that sets the field it is about: the
    field's own flag if one was given, else --config for a scenario field (``scenario.x``)."""
    message = str(error)
    for field, flag in _FIELD_FLAGS.items():
        value = getattr(args, flag.removeprefix("--").replace("-", "_"), None)
        found = re.match(rf"(scenario\.)?{re.escape(field)}: ", message)
        if value is not None and found:
            return f"{flag} {value}: {message[found.end():]}"
    config = getattr(args, "config", None)
    if isinstance(error, ConfigError) and config is not None and message.startswith("scenario."):
        return f"--config {config}: {message}"
    return message
