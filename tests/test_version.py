"""The version and the provenance a result file records (command, commit, date)."""

from __future__ import annotations

import datetime
import subprocess

from ftdrake.version import result_provenance, run_command, source_commit
from tests.helpers import ROOT


def test_the_command_is_written_as_a_user_types_it():
    assert run_command(["/venv/bin/ftdrake", "demo", "--out", "a b"]) == "ftdrake demo --out 'a b'"
    assert run_command(["/src/ftdrake/__main__.py", "study", "--quick"]) == "ftdrake study --quick"
    assert run_command(["benchmarks/x.py", "--n", "3"]) == "python benchmarks/x.py --n 3"


def test_the_commit_is_the_trees_git_description():
    described = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=ROOT,
                               capture_output=True, text=True, check=True).stdout.strip()
    assert source_commit() == described
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                          capture_output=True, text=True, check=True).stdout.strip()
    assert source_commit().startswith(head[:7]) or head[:7] in source_commit()


def test_a_result_file_records_command_commit_and_date():
    record = result_provenance("ftdrake demo")
    assert record["command"] == "ftdrake demo"
    assert record["commit"] == source_commit()
    today = datetime.datetime.now(datetime.timezone.utc).date()
    assert abs((datetime.date.fromisoformat(record["written"]) - today).days) <= 1
