"""MkDocs hook: each command's usage, from the ``ftdrake`` argparse parser at build time.

A page writes ``<!-- ftdrake-usage: train -->`` where ``ftdrake train --help`` belongs (``*``:
every command, ``ftdrake``: the top level). The parser is the one ``ftdrake`` builds when it
runs (``ftdrake.cli.main``), captured at its ``parse_args`` call, so the text is what a user
sees and never goes stale. A marker naming no command is a warning (it fails the strict
build); a command that no page but the reference mentions is reported too.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MARKER = re.compile(r"<!-- ftdrake-usage: ([\w*-]+) -->")
WIDTH = "80"  # COLUMNS: argparse wraps at 78 columns, the code blocks' width on the site
LOG = logging.getLogger("mkdocs.plugins.ftdrake.cli_usage")


class _Captured(Exception):
    def __init__(self, parser):
        super().__init__("parser captured")
        self.parser = parser


def build_parser() -> argparse.ArgumentParser:
    """The parser ``ftdrake`` builds (through ``ftdrake.cli.main``'s own code path)."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from ftdrake.cli import main as cli_main  # noqa: PLC0415 (after the path is set)

    module = sys.modules[cli_main.__module__]
    if hasattr(module, "build_parser"):
        return module.build_parser()

    def capture(self, *args, **kwargs):  # noqa: ARG001
        raise _Captured(self)

    originals = (argparse.ArgumentParser.parse_args, argparse.ArgumentParser.parse_known_args)
    argparse.ArgumentParser.parse_args = capture
    argparse.ArgumentParser.parse_known_args = capture
    try:
        cli_main(["--help"])
    except _Captured as captured:
        return captured.parser
    finally:
        argparse.ArgumentParser.parse_args, argparse.ArgumentParser.parse_known_args = originals
    raise RuntimeError("ftdrake.cli.main returned without parsing its arguments")


def subcommands(parser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:  # argparse keeps sub-parsers only here
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def usage(parser) -> str:
    with _columns(WIDTH):
        return parser.format_help().rstrip() + "\n"


@contextlib.contextmanager
def _columns(width: str):
    before = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = width
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = before


def _block(title: str | None, text: str) -> str:
    head = f"### `{title}`\n\n" if title else ""
    return f"{head}```text\n{text}```\n"


_state: dict = {}


def on_pre_build(config):  # noqa: ARG001
    parser = build_parser()
    _state["parser"] = parser
    _state["commands"] = subcommands(parser)
    _state["mentioned"] = set()


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001
    commands = _state["commands"]

    def replace(match):
        name = match.group(1)
        if name == "*":
            return "\n".join(_block(f"ftdrake {cmd}", usage(p)) for cmd, p in commands.items())
        if name == "ftdrake":
            return _block(None, usage(_state["parser"]))
        if name not in commands:
            LOG.warning(f"{page.file.src_uri}: <!-- ftdrake-usage: {name} --> names no command "
                        f"of ftdrake (it has {', '.join(commands)})")
            return f"`ftdrake {name}`: no such command"
        _state["mentioned"].add(name)
        return _block(None, usage(commands[name]))

    return MARKER.sub(replace, markdown)


def on_post_build(config):  # noqa: ARG001
    missing = sorted(set(_state["commands"]) - _state["mentioned"])
    if missing:
        LOG.warning("commands with no page in the user guide (add "
                    f"<!-- ftdrake-usage: NAME --> to one): {', '.join(missing)}")
