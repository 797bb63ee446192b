"""The command line's grammar: one spelling per concept, old spellings that still work and say
what replaces them, every number checked, defaults shown, ``--version``, and ``--help`` listing
every command."""

from __future__ import annotations

import argparse
import ast
import re
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import pytest

from ftdrake.cli import args as a
from ftdrake.cli import study as study_cli
from ftdrake.cli.main import build_parser, main

COMMANDS = ["simulate", "collect", "train", "evaluate", "export", "replay", "calibrate", "serve",
            "record", "demo", "evaluate-detection", "study", "learn-feedforward", "results",
            "export-correction"]
# Every command that runs longer than a moment takes --quiet.
LONG_COMMANDS = set(COMMANDS) - {"export", "export-correction"}


def commands() -> dict[str, argparse.ArgumentParser]:
    sub = next(x for x in build_parser()._actions if isinstance(x, argparse._SubParsersAction))
    return dict(sub.choices)


def options(parser: argparse.ArgumentParser):
    return [x for x in parser._actions if x.option_strings and x.help is not argparse.SUPPRESS]


# -- --version, --help --------------------------------------------------------------------------
def test_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    try:
        expected = version("ftdrake")
    except PackageNotFoundError:
        expected = "0.0.0+unknown"
    assert capsys.readouterr().out == f"ftdrake {expected}\n"


def test_help_lists_every_command_with_a_description(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "100")
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    listing = text[text.index("commands:"):]
    listed = dict(re.findall(r"^    (\S+)\s+(\S.*)$", listing, flags=re.MULTILINE))
    assert list(listed) == COMMANDS == list(commands())
    assert all(len(line) > 10 for line in listed.values()), listed


def test_each_command_help_shows_its_defaults(monkeypatch):
    monkeypatch.setenv("COLUMNS", "2000")  # no wrapping inside an option's help
    for name, parser in commands().items():
        # One entry per option: its invocation, then its help (on the next line when long).
        entries = re.split(r"\n(?=  -)", parser.format_help())
        for option in options(parser):
            if option.default is None or (option.nargs == 0 and not isinstance(
                    option, argparse.BooleanOptionalAction)):
                continue
            line = next(x for x in entries if x.strip().startswith(
                ", ".join(option.option_strings)))
            shown = ("--html" if option.default else "--no-html") if isinstance(
                option, argparse.BooleanOptionalAction) else option.default
            assert f"(default: {shown})" in line, (name, line)


def test_long_commands_take_quiet():
    quiet = {name for name, parser in commands().items()
             if any(o.option_strings == ["--quiet"] for o in options(parser))}
    assert quiet >= LONG_COMMANDS, LONG_COMMANDS - quiet


# -- one spelling per concept ------------------------------------------------------------------
def test_one_spelling_per_concept():
    """The concepts several commands share have one flag: no command has another spelling
    visible in its help, and each spelling means one thing (its type or choices)."""
    hidden_or_gone = {"--scenario", "--dask", "--scheduler", "--meshcat-html"}
    seen = {}
    for name, parser in commands().items():
        flags = {s: o for o in options(parser) for s in o.option_strings}
        assert not hidden_or_gone & set(flags), name
        for flag in ("--trajectory", "--cluster", "--model", "--kind", "--jobs", "--seed",
                     "--config", "--quiet", "--html"):
            if flag in flags:
                o = flags[flag]
                seen.setdefault(flag, set()).add((o.type, type(o).__name__))
    assert seen["--model"] == {(a.existing_file, "_StoreAction"),
                               (a.existing_file, "_AppendAction")}
    assert seen["--cluster"] == {(a.cluster_address, "_StoreAction")}
    assert seen["--jobs"] == {(a.jobs, "_StoreAction")}
    assert seen["--seed"] == {(a.seed, "_StoreAction")}
    assert seen["--config"] == {(a.existing_file, "_StoreAction")}
    assert seen["--html"] == {(None, "BooleanOptionalAction")}
    assert {cmd for cmd, p in commands().items()
            if any("--trajectory" in o.option_strings for o in options(p))} == {
        "simulate", "collect", "learn-feedforward"}
    assert {cmd for cmd, p in commands().items()
            if any("--kind" in o.option_strings for o in options(p))} == {"train"}


def test_trajectory_choices_are_the_librarys_lists():
    from ftdrake.config import TRAJECTORY_KINDS
    from ftdrake.sim.collection import FREE_KINDS

    choices = {name: next(o.choices for o in options(p) if "--trajectory" in o.option_strings)
               for name, p in commands().items()
               if any("--trajectory" in o.option_strings for o in options(p))}
    assert choices == {"simulate": TRAJECTORY_KINDS, "collect": FREE_KINDS,
                       "learn-feedforward": TRAJECTORY_KINDS}


# (command, old spelling, new spelling, the other arguments the command needs)
OLD_SPELLINGS = [
    ("simulate", ["--scenario", "free"], ["--trajectory", "fourier"], []),
    ("simulate", ["--meshcat-html"], ["--html"], []),
    ("collect", ["--kind", "random"], ["--trajectory", "random"], []),
    ("collect", ["--dask", "tcp://10.0.0.5:8786"], ["--cluster", "tcp://10.0.0.5:8786"], []),
    ("train", ["--model", "svr"], ["--kind", "svr"], ["--data", "{data}", "--out", "m.ftd"]),
    ("train", ["--dask", "h:8786"], ["--cluster", "h:8786"],
     ["--data", "{data}", "--out", "m.ftd"]),
    ("study", ["--scheduler", "tcp://h:8786"], ["--cluster", "tcp://h:8786"], []),
]


@pytest.mark.parametrize(("command", "old", "new", "rest"), OLD_SPELLINGS,
                         ids=[f"{c} {o[0]}" for c, o, _, _ in OLD_SPELLINGS])
def test_old_spelling_still_works_and_names_the_new_one(command, old, new, rest, tmp_path,
                                                        capsys):
    rest = [x.format(data=tmp_path / "log.csv") for x in rest]
    (tmp_path / "log.csv").write_text("t\n")
    parsed_new = build_parser().parse_args([command, *new, *rest])
    assert capsys.readouterr().err == ""
    parsed_old = build_parser().parse_args([command, *old, *rest])
    assert vars(parsed_old) == vars(parsed_new)
    assert vars(parsed_new) != vars(build_parser().parse_args([command, *rest]))
    assert capsys.readouterr().err == (
        f"ftdrake {command}: warning: {' '.join(old)} is deprecated and will be removed in the "
        f"next release; use {' '.join(new)}\n")


def test_old_spellings_are_not_offered_nor_named_in_help(monkeypatch):
    """--help shows the one spelling to use; the old one is named only when it is used."""
    monkeypatch.setenv("COLUMNS", "2000")
    for command, old, new, _ in OLD_SPELLINGS:
        text = commands()[command].format_help()
        usage, entries = text.split("\n\n", 1)[0], re.split(r"\n(?=  -)", text)
        assert old[0] not in usage and not any(x.strip().startswith(old[0]) for x in entries)
        entry = next(x for x in entries if x.strip().startswith(new[0]))
        assert "(replaces" not in entry and old[0] not in entry, entry


def test_an_old_spelling_is_checked_as_the_new_one(capsys):
    with pytest.raises(SystemExit):
        main(["collect", "--dask", "nohost"])
    assert "error: argument --dask: must be a Dask scheduler address" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["simulate", "--scenario", "fourier"])  # the old flag took free|contact
    assert "argument --scenario: invalid choice: 'fourier'" in capsys.readouterr().err


def test_deprecated_spelling_action(capsys):
    """The action alone, on a parser of its own: a value, a mapped value, a flag."""
    parser = argparse.ArgumentParser(prog="tool")
    count = parser.add_argument("--count", type=a.positive_int, default=1)
    a.add_deprecated(parser, "--n", count)
    mode = parser.add_argument("--mode", choices=["x", "y"], default="x")
    a.add_deprecated(parser, "--old-mode", mode, values={"a": "x", "b": "y"})
    flag = parser.add_argument("--fast", action="store_true")
    a.add_deprecated(parser, "--quick", flag)
    parsed = parser.parse_args(["--n", "3", "--old-mode", "b", "--quick"])
    assert (parsed.count, parsed.mode, parsed.fast) == (3, "y", True)
    assert capsys.readouterr().err.splitlines() == [
        f"tool: warning: {old} is deprecated and will be removed in the next release; "
        f"use {new}" for old, new in (("--n 3", "--count 3"), ("--old-mode b", "--mode y"),
                                      ("--quick", "--fast"))]
    assert parser.parse_args([]).count == 1 and capsys.readouterr().err == ""
    with pytest.raises(SystemExit):
        parser.parse_args(["--n", "0"])  # the new spelling's check
    assert "argument --n: must be a whole number >= 1" in capsys.readouterr().err


# -- every number checked --------------------------------------------------------------------------
# A value each number type must refuse (in the format it parses, outside its range).
OUT_OF_RANGE = {a.positive_int: "0", a.positive_float: "0", a.non_negative_int: "-1",
                a.finite_float: "inf", a.seed: "4294967296", a.jobs: "-2",
                study_cli.halving_factor: "1", study_cli.iteration_cap: "-3"}


def test_every_numeric_flag_is_checked(capsys):
    """No option parses a bare int or float; each checked one refuses a value outside its
    range, naming the flag, the range and the value."""
    checked = 0
    for name, parser in commands().items():
        for option in options(parser):
            assert option.type not in (int, float), (name, option.option_strings)
            if option.type not in OUT_OF_RANGE:
                continue
            bad = OUT_OF_RANGE[option.type]
            with pytest.raises(SystemExit):
                main([name, option.option_strings[0], bad])
            last = capsys.readouterr().err.strip().splitlines()[-1]
            assert last.startswith(f"ftdrake {name}: error: argument "
                                   f"{option.option_strings[0]}: must be "), last
            assert last.endswith(f"got {bad!r}"), last
            checked += 1
    assert checked >= 40


@pytest.mark.parametrize(("convert", "good", "bad"), [
    (a.positive_int, {"1": 1, "12": 12}, ["0", "-1", "1.5", "x", ""]),
    (a.positive_float, {"0.5": 0.5, "1e3": 1000.0}, ["0", "-0.1", "inf", "nan", "x"]),
    (a.non_negative_int, {"0": 0, "4": 4}, ["-1", "0.5", "x"]),
    (a.finite_float, {"-2.5": -2.5, "0": 0.0}, ["inf", "-inf", "nan", "x"]),
    (a.seed, {"0": 0, "4294967295": 2**32 - 1}, ["-1", "4294967296", "1.0"]),
    (a.jobs, {"-1": -1, "1": 1, "8": 8}, ["0", "-2", "2.5"]),
])
def test_number_types_accept_their_range_only(convert, good, bad):
    for text, value in good.items():
        assert convert(text) == value and type(convert(text)) is type(value)
    for text in bad:
        with pytest.raises(argparse.ArgumentTypeError, match=re.escape(f"; got {text!r}")):
            convert(text)


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:8786", "10.0.0.5:8786", "h:1",
                                     "tls://scheduler.example.org:8786", "tcp://[::1]:8786"])
def test_cluster_address_accepts_what_dask_connects_to(address):
    from distributed.comm.addressing import parse_address, parse_host_port

    assert a.cluster_address(address) == address
    host, port = parse_host_port(parse_address(address)[1])  # dask reads it the same way
    assert port == int(address.rsplit(":", 1)[1]) and host


@pytest.mark.parametrize("address", ["nohost", "tcp://h", "h:0", "h:65536", "tcp://a b:1",
                                     "ftp://h:21", "h:port", ""])
def test_cluster_address_refuses_what_dask_cannot_connect_to(address):
    with pytest.raises(argparse.ArgumentTypeError, match=r"\[PROTOCOL://\]HOST:PORT"):
        a.cluster_address(address)


# -- the command line's modules ----------------------------------------------------------------
def test_command_modules_do_not_import_main():
    """main assembles the parser from the command modules; none imports it back (shared
    helpers live in cli/args.py)."""
    folder = Path(a.__file__).parent
    for path in folder.glob("*.py"):
        if path.name in ("main.py", "__init__.py"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                assert node.module != "main" and not (
                    node.module is None and any(x.name == "main" for x in node.names)), path
