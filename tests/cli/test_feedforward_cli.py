"""`ftdrake learn-feedforward`'s record of what produced its result files."""

import subprocess
import sys

from ftdrake.cli.feedforward import provenance
from tests.helpers import ROOT


def test_provenance_names_the_command_and_the_checked_out_commit(monkeypatch):
    monkeypatch.setattr(sys, "argv", ["ftdrake", "learn-feedforward", "--two-part"])
    dut = provenance()
    assert dut["command"] == "ftdrake learn-feedforward --two-part"
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                          text=True, check=True).stdout.strip()
    assert head[:7] in dut["commit"]


def test_family_needs_two_part(capsys):
    from ftdrake.cli.main import main

    assert main(["learn-feedforward", "--family", "quick"]) == 2
    assert "add --two-part" in capsys.readouterr().err
