"""Getting started's command-line path works as written: the ``ftdrake`` commands of the
``bash`` block under "A first model", run top to bottom in one folder, with less data
(``collect`` makes 2 runs of 3 s instead of 4 of 10); the contact scenario's press is the one
contact the replayed chain finds."""

from __future__ import annotations

import json
import re
import shlex

import pandas as pd
import pytest

from ftdrake.cli.main import main
from tests.helpers import ROOT

PAGE = ROOT / "docs" / "getting-started.md"
SMALLER = {("collect", "--trajectories"): "2", ("collect", "--duration"): "3"}


def section_commands(heading: str) -> list[list[str]]:
    """The ``ftdrake`` commands of the ``bash`` blocks of the page's section `heading`, in
    order, as the shell splits them."""
    text = PAGE.read_text()
    section = text[text.index(f"## {heading}\n"):]
    section = section[:section.find("\n## ", 1) if "\n## " in section[1:] else None]
    blocks = re.findall(r"^```bash\n(.*?)^```", section, re.DOTALL | re.MULTILINE)
    commands = [shlex.split(line, comments=True) for b in blocks for line in b.splitlines()]
    return [c[1:] for c in commands if c and c[0] == "ftdrake"]


def smaller(argv: list[str]) -> list[str]:
    """`argv` with the sizes of :data:`SMALLER` (each must be on the page)."""
    argv = list(argv)
    for (command, flag), value in SMALLER.items():
        if argv[0] == command:
            argv[argv.index(flag) + 1] = value
    return argv


@pytest.mark.slow
def test_the_command_line_path_runs_as_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    commands = section_commands("A first model")
    assert [c[0] for c in commands] == ["collect", "train", "simulate", "replay"]
    outputs = []
    for argv in map(smaller, commands):
        code = main(argv)
        out, err = capsys.readouterr()
        assert code == 0, (argv, err[-3000:])
        outputs.append(out)
    assert json.loads(outputs[0])["trajectories"] == 2
    assert "saved model.ftd" in outputs[1] and "mass" in outputs[1]  # the physics model
    truth = pd.read_parquet(tmp_path / "contact" / "log.parquet")
    assert truth["contact_true"].any()
    summary = json.loads(outputs[3].strip().splitlines()[-1])
    assert summary["rows"] == len(truth) and summary["contact_episodes"] == 1
    replayed = pd.read_parquet(tmp_path / "contact" / "replay.parquet")
    detected = replayed.loc[replayed["contact"] > 0.5, "t"]
    assert detected.iloc[0] >= truth.loc[truth["contact_true"] > 0.5, "t"].iloc[0]
