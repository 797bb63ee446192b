"""One command-line grammar across the commands: the log a command reads is ``--data`` (old
spellings still work and warn), the live commands say both transports, help texts write
defaults and choices one way and carry no notes about replaced spellings, a flag error shows
the command's short usage line, an unknown flag the usage of the command it was given to,
``train --quiet`` prints no table, and the commands index lists every command."""

from __future__ import annotations

import argparse
import re

import pytest

from ftdrake.cli.main import COMMANDS, build_parser, main
from tests.helpers import ROOT, UR3_DATA, UR3_URDF


def commands() -> dict[str, argparse.ArgumentParser]:
    sub = next(x for x in build_parser()._actions if isinstance(x, argparse._SubParsersAction))
    return dict(sub.choices)


def options(parser):
    return [x for x in parser._actions if x.option_strings and x.help is not argparse.SUPPRESS]


def help_texts():
    """(command, option, its help as --help prints it, defaults expanded)."""
    for name, parser in commands().items():
        formatter = parser._get_formatter()
        for option in options(parser):
            yield name, option.option_strings[0], formatter._expand_help(option)


def error_of(capsys, *argv) -> list[str]:
    with pytest.raises(SystemExit) as exit_:
        main([str(a) for a in argv])
    assert exit_.value.code == 2
    return capsys.readouterr().err.strip().splitlines()


# -- the log a command reads -------------------------------------------------------------------
def test_every_command_that_reads_a_log_takes_it_as_data():
    readers = {name for name, parser in commands().items()
               if any(o.option_strings == ["--data"] for o in options(parser))}
    assert readers == {"train", "evaluate", "calibrate", "replay", "record"}
    for name, parser in commands().items():
        visible = {s for o in options(parser) for s in o.option_strings}
        assert not {"--log", "--from-log"} & visible, name


@pytest.mark.parametrize(("command", "old", "rest"), [
    ("replay", "--log", ["--model", "{model}", "--out", "{out}"]),
    ("record", "--from-log", ["--out", "{out}"]),
])
def test_old_log_spellings_still_work_and_name_data(command, old, rest, tmp_path, capsys):
    log, model = tmp_path / "log.csv", tmp_path / "m.ftd"
    log.write_text("t\n")
    model.write_text("")
    rest = [x.format(model=model, out=tmp_path / "r.csv") for x in rest]
    parsed_new = build_parser().parse_args([command, "--data", str(log), *rest])
    assert capsys.readouterr().err == ""
    parsed_old = build_parser().parse_args([command, old, str(log), *rest])
    assert vars(parsed_old) == vars(parsed_new) and parsed_new.data == log
    assert capsys.readouterr().err == (
        f"ftdrake {command}: warning: {old} {log} is deprecated and will be removed in the "
        f"next release; use --data {log}\n")


def test_replay_takes_no_lcm_url(capsys, tmp_path):
    (tmp_path / "log.csv").write_text("t\n")
    (tmp_path / "m.ftd").write_text("")
    lines = error_of(capsys, "replay", "--model", tmp_path / "m.ftd", "--data",
                     tmp_path / "log.csv", "--out", tmp_path / "r.csv", "--lcm", "memq://")
    assert lines == ["usage: ftdrake replay --model FILE --data FILE --out FILE [OPTIONS]",
                     "ftdrake replay: error: unrecognized arguments: --lcm memq://"]


def test_live_commands_name_both_transports(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "100")
    with pytest.raises(SystemExit):
        main(["--help"])
    listing = capsys.readouterr().out
    for name in ("serve", "record"):
        line = next(x for x in listing.splitlines() if x.strip().startswith(name + " "))
        assert "(LCM or ROS 2)" in line, line
        assert "(LCM or ROS 2)" in commands()[name].description


# -- help texts: one style ---------------------------------------------------------------------
def test_help_names_no_replaced_spelling():
    for name, flag, text in help_texts():
        assert "(replaces" not in text, (name, flag, text)
        assert not re.search(r"--[\w-]+ [\w-]+ was ", text), (name, flag, text)  # old → new


def test_defaults_are_written_one_way():
    """Every default a help text states is ``(default: X)``, once, at its end."""
    stated = 0
    for name, flag, text in help_texts():
        said = re.findall(r"\bdefault\b", text)
        if said:
            assert len(said) == 1 and re.search(r"\(default: [^()]*(\([^()]*\)[^()]*)*\)$",
                                                text), (name, flag, text)
            stated += 1
    assert stated >= 60


def test_choices_are_written_one_way(monkeypatch):
    """An option with choices shows them as its value, ``--flag A|B``, or when they do not fit
    a line, as ``--flag NAME`` with ``(NAME: A | B)`` in its help; never argparse's
    ``{A,B}``."""
    monkeypatch.setenv("COLUMNS", "2000")
    shown = 0
    for name, parser in commands().items():
        text = parser.format_help()
        assert "{" not in text.split("\n\n")[0], name  # argparse's {a,b} in the usage
        for option in options(parser):
            if option.choices is None or option.nargs == 0:
                continue
            flag, choices = option.option_strings[0], [str(c) for c in option.choices]
            name_ = option.dest.upper()
            assert (f"{flag} {'|'.join(choices)}" in text
                    or (f"{flag} {name_}" in text and f"({name_}: {' | '.join(choices)})" in text)
                    ), (name, flag)
            shown += 1
    assert shown >= 10


def test_usage_fits_78_columns(monkeypatch):
    """At 80 columns (the site renders usage at that width) no line is wider than 78."""
    monkeypatch.setenv("COLUMNS", "80")
    for name, parser in {"ftdrake": build_parser(), **commands()}.items():
        wide = [line for line in parser.format_help().splitlines() if len(line) > 78]
        assert not wide, (name, wide)


# -- errors ------------------------------------------------------------------------------------
def test_a_flag_error_shows_the_short_usage_line(capsys):
    lines = error_of(capsys, "train", "--data", "no-such.csv", "--out", "m.ftd")
    assert lines == ["usage: ftdrake train --data FILE --out MODEL [OPTIONS]",
                     "ftdrake train: error: argument --data: no-such.csv: no such file or folder"]
    lines = error_of(capsys, "serve")
    assert lines == ["usage: ftdrake serve --model FILE [OPTIONS]",
                     "ftdrake serve: error: the following arguments are required: --model"]


def test_an_unknown_flag_shows_the_commands_usage(capsys):
    lines = error_of(capsys, "simulate", "--model", "m.ftd")
    assert lines == ["usage: ftdrake simulate [OPTIONS]",
                     "ftdrake simulate: error: unrecognized arguments: --model m.ftd"]
    lines = error_of(capsys, "--bogus", "demo")
    assert lines[0] == "usage: ftdrake [OPTIONS] COMMAND ..."


# -- train --quiet ------------------------------------------------------------------------------
def test_train_quiet_prints_only_the_file_line(ftdrake, tmp_path):
    argv = ["train", "--data", UR3_DATA / "id1.csv", "--targets", "tau_*", "--velocities",
            "qd_*", "--kind", "physics", "--robot", UR3_URDF, "--preset", "none"]
    code, out, err = ftdrake(*argv, "--out", tmp_path / "loud.ftd")
    assert code == 0 and len(out.splitlines()) > 20  # the identified arm, as a table
    code, out, err = ftdrake(*argv, "--out", tmp_path / "quiet.ftd", "--quiet")
    assert code == 0, err
    assert len(out.splitlines()) == 1 and out.startswith(f"saved {tmp_path / 'quiet.ftd'} (")
    assert "fitting" not in err and "reading" not in err


# -- the commands index ------------------------------------------------------------------------
def test_the_commands_index_lists_every_command():
    index = (ROOT / "docs" / "guide" / "commands" / "index.md").read_text()
    table = index[:index.index("<!-- ftdrake-usage: ftdrake -->")]
    listed = set(re.findall(r"`([a-z-]+)(?: --\w+)?`", table))
    assert set(COMMANDS) <= listed, set(COMMANDS) - listed
