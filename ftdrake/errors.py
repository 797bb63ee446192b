"""The errors ftdrake raises for problems a user can fix, and only those.

Every one derives from :class:`FtdrakeError`; the command line catches that class alone, so a
bug in ftdrake (any other exception) shows its traceback instead of passing for a user error.
Each also derives from ``ValueError`` where it did before, so existing ``except ValueError``
code keeps working.

Advice in a message or warning speaks the user's language: :func:`spelled` gives its Python
form (keywords, classes) by default and its command-line form (flags) inside
:func:`command_line_front_end`, which the ``ftdrake`` command enters. A message about one
option names it with :func:`option_name`: the keyword or field name in Python, the flag on the
command line — the library carries no flag names.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Iterator

_COMMAND_LINE: contextvars.ContextVar[bool] = contextvars.ContextVar(
    "ftdrake_command_line", default=False)


def spelled(python: str, command_line: str) -> str:
    """`python` (advice naming keywords and classes), or `command_line` (naming flags) when
    the ``ftdrake`` command runs."""
    return command_line if _COMMAND_LINE.get() else python


_OPTION_SPELLING: contextvars.ContextVar = contextvars.ContextVar(
    "ftdrake_option_name_spelling", default=None)


def option_name(name: str) -> str:
    """How a message names option `name` (a keyword or an options field; ``read.positions``
    for a field of a nested options object): `name` itself in Python; inside
    :func:`command_line_front_end` the flag, ``--`` and the last part with dashes
    (``read.max_rows`` → ``--max-rows``), unless :func:`option_names` chose a spelling."""
    spell = _OPTION_SPELLING.get()
    if spell is not None:
        return spell(name)
    if _COMMAND_LINE.get():
        return "--" + name.rpartition(".")[2].replace("_", "-")
    return name


@contextlib.contextmanager
def option_names(spell) -> Iterator[None]:
    """Within the block, :func:`option_name` returns ``spell(name)`` (a command whose flags
    are not all the options' names with dashes)."""
    token = _OPTION_SPELLING.set(spell)
    try:
        yield
    finally:
        _OPTION_SPELLING.reset(token)


@contextlib.contextmanager
def command_line_front_end() -> Iterator[None]:
    """Within the block, :func:`spelled` advice names the command line's flags."""
    token = _COMMAND_LINE.set(True)
    try:
        yield
    finally:
        _COMMAND_LINE.reset(token)


class FtdrakeError(Exception):
    """Base class: something the user gave (a file, a setting, data) is wrong; the message
    names it and, where there is one, the option that fixes it."""


class ConfigError(FtdrakeError, ValueError):
    """A configuration field is missing or invalid; the message names the field."""


class LogError(FtdrakeError, ValueError):
    """A robot log cannot be read or fails a check (units, time, columns)."""


class ModelFileError(FtdrakeError, ValueError):
    """A model file is unreadable, corrupted, untrusted or of another format version."""


class TrajectoryError(FtdrakeError, ValueError):
    """A trajectory violates a limit or cannot be built; the message says where and when."""


class RobotModelError(FtdrakeError, ValueError):
    """A robot description (URDF/SDF, frames, packages) cannot be used."""
