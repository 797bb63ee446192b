"""The results pages show figures their result files hold, and say how those files were made.

A figure on a page under ``docs/results/`` is rendered at the docs build from a result file
(``docs/hooks/result_files.py``: ``<!-- result-source FILE -->``, ``{{ KEY | FORMAT }}``,
``<!-- result-table FILE -->``). These checks fail when:

* a page cites no result file and does not say why (``<!-- no-result-file: REASON -->``);
* a cited file records no command and commit, or a commit git does not know;
* a cited key is not in its file (the page would not build);
* a table cell holds a typed figure, unless the table is marked ``<!-- typed: REASON -->`` (a
  model parameter, an earlier round kept for history, a run no file records);
* a typed figure anywhere on a page copies one of the files it cites (to the digits shown):
  edit a figure of a file into the page by hand and this fails; render it instead;
* the result files are written by a command ``ftdrake results`` does not know.
"""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess

import pytest

from ftdrake.experiments.result_pages import RESULTS
from tests.helpers import ROOT

DOCS = ROOT / "docs"
PAGES = sorted((DOCS / "results").glob("*.md"))

_spec = importlib.util.spec_from_file_location("result_files", DOCS / "hooks/result_files.py")
hook = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hook)

NO_FILE = re.compile(r"<!--\s*no-result-file:\s*(\S.{10,}?)\s*-->", re.DOTALL)
TYPED_TABLE = re.compile(r"<!--\s*typed:\s*(\S.{10,}?)\s*-->", re.DOTALL)
NUMBER = re.compile(r"(?<![\w.])[-−]?\d+(?:[.,]\d+)?(?:e[-+]?\d+)?(?![\w])")
CODE = re.compile(r"```.*?```|`[^`\n]*`", re.DOTALL)
COMMENT = re.compile(r"<!--.*?-->", re.DOTALL)
LINK = re.compile(r"\]\([^)]*\)")
MIN_DIGITS = 3  # shorter typed figures (0.12, 2.2) match some value of a big file by chance


def cited(text: str) -> list:
    return hook.SOURCE.findall(text) + [m.group(1) for m in hook.TABLE.finditer(text)] + [
        m.group(1).split(":")[0].strip() for m in hook.VALUE.finditer(text)
        if re.match(r"^\s*[\w./-]+\.json\s*:", m.group(1))]


def strip_rendered(text: str) -> str:
    """The page's own typing: no macro, comment, code, link target or typed-on-purpose figure."""
    for pattern in (hook.TABLE, COMMENT, hook.VALUE, hook.TYPED, CODE, LINK):
        text = pattern.sub(" ", text)
    return text


def tables(text: str):
    """(the lines before it, [rows]) of each Markdown table, the header and rule excluded."""
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        if lines[i].lstrip().startswith("|") and i + 1 < len(lines) and re.match(
                r"^\s*\|\s*:?-{3,}", lines[i + 1]):
            start = i
            i += 2
            rows = []
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                rows.append(lines[i])
                i += 1
            yield "\n".join(lines[max(0, start - 4):start]), rows
        else:
            i += 1


def without_typed_tables(text: str) -> str:
    """`text` without the tables marked ``<!-- typed: REASON -->`` (figures no file holds)."""
    lines = text.splitlines()
    for before, rows in tables(text):
        if TYPED_TABLE.search(before):
            drop = set(rows)
            lines = [x for x in lines if x not in drop]
    return "\n".join(lines)


def typed_figures(row: str) -> list:
    """The figures typed by hand in a table row's cells after its label."""
    row = hook.VALUE.sub(" ", hook.TYPED.sub(" ", row))
    cells = [c for c in row.strip().strip("|").split("|")][1:]
    return [n for c in cells for n in NUMBER.findall(CODE.sub(" ", c))]


def leaves(data):
    """Every number in a JSON document but those of its per-run records (lists of objects:
    every press, every run, every point of a curve), which a page summarises, never copies."""
    if isinstance(data, dict):
        for v in data.values():
            yield from leaves(v)
    elif isinstance(data, list):
        if any(isinstance(v, dict) for v in data):
            return
        for v in data:
            yield from leaves(v)
    elif isinstance(data, (int, float)) and not isinstance(data, bool):
        yield float(data)


def significant(text: str) -> int:
    """The significant digits of a typed figure: ``0.0058`` → 2, ``12.50`` → 4."""
    return len(re.sub(r"\D", "", text).lstrip("0"))


def copies(figure: str, values) -> bool:
    """`figure` (as typed) equals one of `values` rounded to the digits it shows."""
    text = figure.replace("−", "-").replace(",", ".")
    decimals = len(text.partition(".")[2])
    typed = float(text)
    return any(round(v, decimals) == typed or round(abs(v), decimals) == abs(typed)
               for v in values)


def page_id(path):
    return path.name


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_each_results_page_cites_its_files_or_says_why_not(page):
    text = page.read_text(encoding="utf-8")
    if not (cited(text) or NO_FILE.search(text)):
        pytest.fail(f"{page.name}: cite the result file its figures come from (<!-- "
                    "result-source FILE -->) or say why there is none (<!-- no-result-file: "
                    "REASON -->)")


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_each_cited_file_records_its_command_and_a_known_commit(page):
    for name in set(cited(page.read_text(encoding="utf-8"))):
        prov = hook.load(name).get("provenance") or {}
        assert prov.get("command") and prov.get("commit"), f"docs/{name}: no provenance"
        commit = prov["commit"].removesuffix("-dirty").rsplit("-g", 1)[-1]
        known = subprocess.run(["git", "cat-file", "-e", f"{commit}^{{commit}}"], cwd=ROOT,
                               capture_output=True, check=False)
        assert known.returncode == 0, f"docs/{name}: commit {prov['commit']} is not in git"


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_each_page_renders_from_its_files(page):
    text = page.read_text(encoding="utf-8")
    rendered = hook.render(text, f"results/{page.name}")  # a missing key raises here
    assert "{{" not in rendered and "result-source" not in rendered
    for name in set(hook.SOURCE.findall(text)):
        prov = hook.load(name)["provenance"]
        assert f"`{prov['command']}` at commit `{prov['commit']}`" in rendered


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_no_table_holds_a_typed_figure(page):
    problems = []
    for before, rows in tables(COMMENT.sub(lambda m: m.group(0) if TYPED_TABLE.match(
            m.group(0)) else "", page.read_text(encoding="utf-8"))):
        if TYPED_TABLE.search(before):
            continue
        problems += [f"{row.strip()[:70]}…: {figures}" for row in rows
                     if (figures := typed_figures(row))]
    assert not problems, (f"{page.name}: tables with typed figures (render them from the "
                          "result file, or mark the table <!-- typed: REASON -->):\n"
                          + "\n".join(problems))


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_no_typed_figure_copies_a_cited_file(page):
    text = page.read_text(encoding="utf-8")
    values = [v for name in set(cited(text)) for v in leaves(hook.load(name))
              if v not in (0.0, 1.0)]
    own = strip_rendered(without_typed_tables(text))
    figures = [f for f in NUMBER.findall(own)
               if significant(f) >= MIN_DIGITS and ("." in f or "," in f)]
    copied = sorted({f for f in figures if copies(f, values)})
    assert not copied, (f"{page.name}: typed figures equal to its result files' (render them "
                        f"with {{{{ KEY | FORMAT }}}}, or write {{{{ typed X }}}} for a figure "
                        f"that only happens to be equal): {copied}")


def test_every_cited_file_is_written_by_a_command_results_knows():
    written = {target for r in RESULTS for _, _, target in r.files}
    for page in PAGES:
        for name in cited(page.read_text(encoding="utf-8")):
            assert name in written, (f"{page.name} cites docs/{name}, which no entry of "
                                     "ftdrake.experiments.result_pages.RESULTS writes")


def test_the_hook_renders_values_tables_and_provenance(tmp_path, monkeypatch):
    monkeypatch.setattr(hook, "DOCS", tmp_path)
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "t.json").write_text(json.dumps({
        "hole a": {"two_part_timed": 6.25, "ilc": 1.5}, "slot": {"two_part_timed": 3.0,
                                                                 "ilc": 0.75},
        "list": [0.5, 0.25, 2.0], "provenance": {"command": "ftdrake x", "commit": "abc1234"}}))
    page = ("<!-- result-source r/t.json -->\n{{ list | .2f | range }} {{ list | cells }} "
            '{{ ["hole a"].ilc | .1f }} {{ list[-1] }} {{ list | len }} {{ typed 7.5 }}\n'
            "<!-- result-table r/t.json\nrows: hole a=Ø 20, slot\ncolumns: two_part_timed=timed, "
            "ilc=ILC\nformat: .1f\ncorner: contour\n-->")
    out = hook.render(page, "results/p.md")
    assert "`ftdrake x` at commit `abc1234`" in out and "(../r/t.json)" in out
    assert "0.25–2.00 0.5 | 0.25 | 2 1.5 2 3 7.5" in out
    assert "| contour | timed | ILC |\n| --- | --- | --- |\n| Ø 20 | 6.2 | 1.5 |\n" in out
    assert "| slot | 3.0 | 0.8 |" in out
    for bad, message in [("{{ list[3] }}", "no 3"), ("{{ nope }}", "no 'nope'"),
                         ("{{ r/none.json : a }}", "does not exist")]:
        with pytest.raises(hook.ResultError, match=message):
            hook.render("<!-- result-source r/t.json -->" + bad, "results/p.md")
    code = "`{{ list }}` and\n```\n<!-- result-source FILE -->\n```\n"
    assert hook.render(code, "results/p.md") == code  # code is shown as written
    (tmp_path / "r" / "n.json").write_text("{}")
    with pytest.raises(hook.ResultError, match="no provenance"):
        hook.render("<!-- result-source r/n.json -->", "results/p.md")


def test_the_suites_size_and_time_are_given_once_in_the_readme():
    pattern = re.compile(r"\b\d[\d ,]*\s+tests\b|tests? (?:take|run in) (?:about )?\d")
    for path in [*DOCS.rglob("*.md")]:
        text = path.read_text(encoding="utf-8")
        assert not pattern.search(text), f"{path.relative_to(ROOT)}: {pattern.search(text)[0]!r}"
    assert pattern.search((ROOT / "README.md").read_text(encoding="utf-8")) or (
        "the tests about" in (ROOT / "README.md").read_text(encoding="utf-8"))
