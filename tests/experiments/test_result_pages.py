"""The results' table and regenerator (``ftdrake results``): every command it names parses,
every file it copies is one a results page cites, and a regeneration copies what its commands
wrote into docs/ only when they all succeeded. Nothing here runs an experiment."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ftdrake.cli.main import build_parser, main
from ftdrake.errors import ConfigError, FtdrakeError
from ftdrake.experiments import result_pages as rp
from tests.helpers import ROOT

WORK = ROOT / "out" / "results"


@pytest.mark.parametrize("result", rp.RESULTS, ids=lambda r: r.name)
@pytest.mark.parametrize("quick", [False, True])
def test_every_command_parses_with_the_cli(result, quick, tmp_path):
    parser = build_parser()
    for step in result.steps:
        argv = step.command(tmp_path, quick=quick)
        assert argv[0] == "ftdrake"
        for model in (x for x in argv if x.endswith(".ftd")):  # an earlier step's output
            Path(model).parent.mkdir(parents=True, exist_ok=True)
            Path(model).touch()
        parser.parse_args(argv[1:])


def test_each_step_writes_under_its_own_folder_and_the_files_exist_in_docs():
    names = [s.name for r in rp.RESULTS for s in r.steps]
    for r in rp.RESULTS:
        steps = {s.name for s in r.steps}
        for step, _, target in r.files:
            assert step in steps, (r.name, step)
            assert (ROOT / "docs" / target).is_file(), target
        assert (ROOT / "docs" / r.page).is_file(), r.page
    # a step name shared between results is the same command (run once per call)
    by_name = {}
    for r in rp.RESULTS:
        for s in r.steps:
            assert by_name.setdefault(s.name, s) == s, s.name
    assert len(set(names)) < len(names)  # the demo's models are shared


def test_listing_names_each_page_command_commit_and_time():
    text = rp.listing(rp.RESULTS, WORK)
    for r in rp.RESULTS:
        assert f"docs/{r.page}" in text
        for s in r.steps:
            assert s.shown(WORK) in text
    demo = json.loads((ROOT / "docs/demo/summary.json").read_text())
    assert f"files at {demo['provenance']['commit']}" in text
    assert f"{demo['wall_time_s'] / 60:.1f} min" in text


def test_an_unknown_name_lists_the_names(capsys):
    assert main(["results", "--only", "nope"]) == 2
    err = capsys.readouterr().err
    assert "--only nope: no result named 'nope'" in err and "feedforward" in err
    with pytest.raises(ConfigError, match="demo, detection"):
        rp.find(["nope"])


def test_dry_run_prints_the_commands_and_runs_nothing(capsys, tmp_path):
    assert main(["results", "--dry-run", "--quick", "--only", "detection", "--work",
                 str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"ftdrake demo --no-html --out {tmp_path}/demo --trajectories 1" in out
    assert "evaluate-detection" in out and "--quick" in out
    assert list(tmp_path.iterdir()) == []


def _fake(tmp_path, monkeypatch, code: str):
    """A registry of one result whose command is `python -c code` writing into {out}."""
    docs = tmp_path / "docs"
    (docs / "x").mkdir(parents=True, exist_ok=True)
    (docs / "x" / "r.json").write_text('{"old": true}')
    step = rp.Step("s", ("python", "-c", code, "{out}"))
    result = rp.Result("fake", "results/x.md", (step,), (("s", "r.json", "x/r.json"),), None)
    monkeypatch.setattr(rp, "DOCS", docs)
    return result, docs / "x" / "r.json"


def test_regenerate_copies_the_written_file_into_docs(tmp_path, monkeypatch):
    code = ("import json, pathlib, sys; from ftdrake.version import result_provenance; "
            "o = pathlib.Path(sys.argv[1]); o.mkdir(parents=True); "
            "(o / 'r.json').write_text(json.dumps(dict(v=3, provenance=result_provenance())))")
    result, target = _fake(tmp_path, monkeypatch, code)
    assert rp.regenerate([result], tmp_path / "work", quiet=True) == ["docs/x/r.json"]
    written = json.loads(target.read_text())
    assert written["v"] == 3 and written["provenance"]["commit"]
    # quick: runs, copies nothing
    target.write_text('{"old": true}')
    assert rp.regenerate([result], tmp_path / "work2", quick=True, quiet=True) == []
    assert json.loads(target.read_text()) == {"old": True}


def test_a_failed_or_silent_command_leaves_docs_as_it_was(tmp_path, monkeypatch):
    result, target = _fake(tmp_path, monkeypatch, "import sys; sys.exit(3)")
    with pytest.raises(FtdrakeError, match=r"result fake: `.*python.* -c .*` failed \(exit 3"):
        rp.regenerate([result], tmp_path / "work", quiet=True)
    assert json.loads(target.read_text()) == {"old": True}
    result, target = _fake(tmp_path, monkeypatch, "pass")
    with pytest.raises(ConfigError, match=r"did not write .*r\.json"):
        rp.regenerate([result], tmp_path / "work", quiet=True)
    assert json.loads(target.read_text()) == {"old": True}


def test_without_a_checkouts_docs_folder_regenerate_says_so(tmp_path, monkeypatch):
    monkeypatch.setattr(rp, "DOCS", tmp_path / "site-packages" / "docs")
    with pytest.raises(FtdrakeError, match="needs a checkout of ftdrake"):
        rp.regenerate(rp.RESULTS[:1], tmp_path / "work", quiet=True)
    assert not (tmp_path / "work").exists()
