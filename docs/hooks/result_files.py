"""MkDocs hook: the figures of the results pages, rendered from the result files at build time.

A results page types no measured figure: it names the file that holds it, and the build reads
the value from there. Three forms (``FILE`` is a path under ``docs/``, JSON):

``<!-- result-source FILE -->``
    becomes the line that says how the figures below were made, from the file's
    ``provenance`` record (``ftdrake.version.result_provenance``): the command, the commit and
    the date, with a link to the file. It also makes ``FILE`` the default file of the values
    below it (and the first one that of the values above it). A cited file without a
    ``provenance`` record with ``command`` and ``commit`` fails the build.

``{{ [FILE :] KEY.PATH [| FORMAT] [| MODIFIER] }}``
    one value (``task.gp.tip_rms_mm[5]``, ``models["hybrid (chi2)"].detector``; ``[-1]`` is
    the last item, ``[:3]`` the first three). ``FORMAT`` is Python's format spec (``.3g``,
    ``.2f``, ``.1%``; ``_`` groups thousands with a space); a list is formatted item by item
    and joined by spaces, or by ``MODIFIER``: ``cells`` (table cells, `` | ``), ``range``
    (``min–max``), ``comma``.
    ``min``, ``max``, ``len``, ``sum`` reduce a list or a mapping to one number first;
    ``*1000`` scales (s → ms). ``presses[surface=wall][*].false_positives`` is the list of a
    field over the items whose ``surface`` is ``wall``.

``<!-- result-table FILE`` ... ``-->``
    a Markdown table of a mapping of mappings (``{"row": {"column": value}}``, e.g.
    ``feedforward/transfer.json``), with lines ``key: PATH`` (the mapping inside the file;
    default the whole file), ``rows: a=Label, b`` (default ``*``: every key but
    ``provenance``, in the file's order), ``columns: x=Label, y`` (default ``*``: the first
    row's keys), ``corner: TEXT`` (the header of the row labels), ``format: .2f`` and
    ``missing: –`` (a cell a row does not have; default: the build fails).

``<!-- no-result-file: REASON -->``
    a page whose figures no result file holds (a benchmark that prints them) says so, visibly.
``{{ typed X }}``
    a figure typed on purpose (a ground truth, an earlier round), shown as ``X``.

A key, a file or a record that is missing fails the build with the page, the file and the key,
so a page can never show a figure its file does not hold. ``tests/project/
test_results_pages.py`` checks that no table of a results page holds a typed figure and that no
typed figure on it copies one of the files it cites.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]

SOURCE = re.compile(r"<!--\s*result-source\s+(\S+)\s*-->")
TABLE = re.compile(r"<!--\s*result-table\s+(\S+)\s*\n(.*?)-->", re.DOTALL)
VALUE = re.compile(r"\{\{(?!\s*typed\b)(.+?)\}\}")
TYPED = re.compile(r"\{\{\s*typed\s+(.+?)\s*\}\}")
NO_FILE = re.compile(r"<!--\s*no-result-file:\s*(.+?)\s*-->", re.DOTALL)
KEY_PART = re.compile(r'\["([^"]*)"\]|\[(-?\d+)\]|\[(-?\d*:-?\d*)\]|\[(\*|\w+=[^\]]*)\]'
                      r'|([^.\[\]]+)')
REDUCERS = {"min": min, "max": max, "len": len, "sum": sum}
JOINERS = {"cells": " | ", "comma": ", ", "range": "–"}


class ResultError(ValueError):
    """A citation of a result file that the file does not hold."""


def load(name: str, cache: dict | None = None):
    """The JSON of ``docs/<name>``; a missing or unreadable file is a :class:`ResultError`."""
    if cache is not None and name in cache:
        return cache[name]
    path = DOCS / name
    if not path.is_file():
        raise ResultError(f"result file docs/{name} does not exist")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise ResultError(f"result file docs/{name} is not JSON: {e}") from e
    if cache is not None:
        cache[name] = data
    return data


def key_parts(path: str) -> list:
    """``a.b[2]["c d"][:3][*][k=v]`` → ``["a", "b", 2, "c d", slice(None, 3), "[*]",
    ("k", "v")]``."""
    parts, pos = [], 0
    path = path.strip()
    for m in KEY_PART.finditer(path):
        if path[pos:m.start()] not in ("", "."):
            raise ResultError(f"key {path!r}: cannot read {path[pos:m.start()]!r}")
        quoted, index, span, each, plain = m.groups()
        if span is not None:
            start, stop = (int(x) if x else None for x in span.split(":"))
            parts.append(slice(start, stop))
        elif each is not None:
            parts.append("[*]" if each == "*" else tuple(each.split("=", 1)))
        else:
            parts.append(quoted if quoted is not None else int(index) if index is not None
                         else plain.strip())
        pos = m.end()
    if not parts or path[pos:]:
        raise ResultError(f"key {path!r}: cannot read it (write a.b[0][\"c d\"])")
    return parts


def lookup(data, path: str, name: str):
    """The value at `path` in `data` (the JSON of ``docs/<name>``): ``[*]`` maps the rest of
    the path over a list's items (a mapping's values), ``[k=v]`` keeps the items whose ``k``
    reads ``v``."""
    return _walk(data, key_parts(path), [], name)


def _walk(value, parts: list, done: list, name: str):
    if not parts:
        return value
    part, rest = parts[0], parts[1:]
    if part == "[*]" and isinstance(value, dict):
        return [_walk(v, rest, [*done, "*"], name) for v in value.values()]
    if part == "[*]" or isinstance(part, tuple):
        if not isinstance(value, list):
            raise ResultError(f"docs/{name}: {_where(done)} is not a list ({part})")
        if isinstance(part, tuple):
            kept = [v for v in value if isinstance(v, dict) and str(v.get(part[0])) == part[1]]
            return _walk(kept, rest, [*done, f"{part[0]}={part[1]}"], name)
        return [_walk(v, rest, [*done, "*"], name) for v in value]
    try:
        return _walk(value[part], rest, [*done, part], name)
    except (KeyError, IndexError, TypeError):
        have = (", ".join(map(str, list(value)[:12])) if isinstance(value, dict)
                else f"{len(value)} items" if isinstance(value, list) else repr(value))
        raise ResultError(f"docs/{name} has no {part!r} under {_where(done)} (it has: {have})"
                          ) from None


def _where(done: list) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in done
                   ).lstrip(".") or "the top level"


def fmt(value, spec: str = "") -> str:
    """One value as the page shows it (`spec`: Python's format spec; ``_`` → thin space)."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return str(value) if value is not None else "–"
    if isinstance(value, (int, float)):
        text = format(value, spec) if spec else f"{value:g}"
        text = (text.replace("_", " ").replace("e-0", "e-").replace("e+0", "e+")
                .replace("-", "−"))  # the minus sign the pages write
        return text[:-1] + " %" if text.endswith("%") else text
    raise ResultError(f"{value!r} is not one number (name an item, or use len/min/max)")


def render_value(expr: str, default: str | None, cache: dict | None = None) -> str:
    """The text of one ``{{ [FILE :] KEY | FORMAT | MODIFIER }}``."""
    head, *options = (s.strip() for s in expr.split("|"))
    named = re.match(r"^([\w./-]+\.json)\s*:(.*)$", head, re.DOTALL)
    name, path = (named.group(1), named.group(2)) if named else (default, head)
    if not name:
        raise ResultError(f"{{{{ {expr.strip()} }}}} names no file and no result-source "
                          "is above it")
    value = lookup(load(name, cache), path, name)
    spec, joiner = "", " "
    for option in options:
        if option in REDUCERS:
            value = REDUCERS[option](value.values() if isinstance(value, dict) else value)
        elif re.fullmatch(r"\*\s*[\d.e+-]+", option):
            factor = float(option[1:])
            value = ([v * factor for v in value] if isinstance(value, (list, tuple))
                     else value * factor)
        elif option in JOINERS:
            joiner = JOINERS[option]
            if option == "range":
                value = [min(value), max(value)]
        else:
            spec = option
    if isinstance(value, (list, tuple)):
        return joiner.join(fmt(v, spec) for v in value)
    return fmt(value, spec)


def source_line(name: str, page_path: str, cache: dict | None = None) -> str:
    """The provenance line of ``docs/<name>`` as seen from the page at `page_path`."""
    record = load(name, cache)
    prov = record.get("provenance") if isinstance(record, dict) else None
    if not isinstance(prov, dict) or not prov.get("command") or not prov.get("commit"):
        raise ResultError(f"docs/{name} has no provenance record with command and commit "
                          "(ftdrake.version.result_provenance; regenerate it with "
                          "`ftdrake results --regenerate`)")
    link = os.path.relpath(DOCS / name, (DOCS / page_path).parent).replace(os.sep, "/")
    when = "; ".join(str(prov[k]) for k in ("written", "note") if prov.get(k))
    return (f"**Measured** by `{prov['command']}` at commit `{prov['commit']}`"
            + (f" ({when})" if when else "") + f", in [`{name}`]({link}).\n")


def table_options(body: str) -> dict:
    options = {}
    for line in body.strip().splitlines():
        key, sep, value = line.partition(":")
        if not sep or key.strip() not in ("key", "rows", "columns", "corner", "format",
                                           "missing"):
            raise ResultError(f"result-table: cannot read {line.strip()!r} (lines are key:, "
                              "rows:, columns:, corner:, format:, missing:)")
        options[key.strip()] = value.strip()
    return options


def labelled(text: str, keys) -> list:
    """``a=Label, b`` → ``[("a", "Label"), ("b", "b")]``; ``*`` → every key of `keys`."""
    if text in ("", "*"):
        return [(k, k) for k in keys if k != "provenance"]
    pairs = []
    for item in text.split(","):
        key, _, label = item.partition("=")
        pairs.append((key.strip(), label.strip() or key.strip()))
    return pairs


def render_table(name: str, body: str, cache: dict | None = None) -> str:
    """The Markdown table of ``<!-- result-table FILE ... -->``."""
    options = table_options(body)
    data = load(name, cache)
    table = lookup(data, options["key"], name) if options.get("key") else data
    if not isinstance(table, dict):
        raise ResultError(f"result-table docs/{name}: {options.get('key', 'the file')} is not "
                          "a mapping of rows")
    rows = labelled(options.get("rows", "*"), table)
    first = table[rows[0][0]] if rows and rows[0][0] in table else {}
    columns = labelled(options.get("columns", "*"), first)
    lines = ["| " + " | ".join([options.get("corner", ""), *(c[1] for c in columns)]) + " |",
             "|" + " --- |" * (len(columns) + 1)]
    for key, label in rows:
        row = lookup(data, f'{options.get("key", "")}["{key}"]'.lstrip("."), name)
        cells = []
        for column, _ in columns:
            if column not in row and "missing" in options:
                cells.append(options["missing"])
            else:
                cells.append(fmt(lookup(row, f'["{column}"]', name), options.get("format", "")))
        lines.append("| " + " | ".join([label, *cells]) + " |")
    return "\n".join(lines)


CODE = re.compile(r"```.*?```|`[^`\n]*`", re.DOTALL)


def render(markdown: str, page_path: str) -> str:
    """`markdown` of the page at `page_path` (relative to docs/) with every form rendered;
    code (a fenced block, an inline span) is left as written."""
    code: list = []

    def hide(m):
        code.append(m.group(0))
        return f"\x00{len(code) - 1}\x00"

    rendered = _render(CODE.sub(hide, markdown), page_path)
    return re.sub(r"\x00(\d+)\x00", lambda m: code[int(m.group(1))], rendered)


def _render(markdown: str, page_path: str) -> str:
    cache: dict = {}
    markdown = NO_FILE.sub(lambda m: f"*Not rendered from a result file: {m.group(1)}.*",
                           markdown)
    markdown = TABLE.sub(lambda m: render_table(m.group(1), m.group(2), cache), markdown)
    first = SOURCE.search(markdown)
    out, default, pos = [], first.group(1) if first else None, 0
    for m in SOURCE.finditer(markdown):
        out.append(_values(markdown[pos:m.start()], default, cache))
        default = m.group(1)
        out.append(source_line(default, page_path, cache))
        pos = m.end()
    out.append(_values(markdown[pos:], default, cache))
    return "".join(out)


def _values(text: str, default, cache) -> str:
    text = VALUE.sub(lambda m: render_value(m.group(1), default, cache), text)
    return TYPED.sub(lambda m: m.group(1), text)


def with_sibling_source(markdown: str, page_path: str) -> str:
    """A table page a command writes beside its JSON (``detection/detection.md`` beside
    ``detection.json``) gets that JSON's provenance line under its title."""
    sibling = Path(page_path).with_suffix(".json").as_posix()
    if not (DOCS / sibling).is_file() or page_path.startswith("results/"):
        return markdown
    record = load(sibling)
    if not isinstance(record, dict) or "provenance" not in record:
        return markdown
    title, _, rest = markdown.partition("\n")
    return f"{title}\n\n{source_line(sibling, page_path)}\n{rest}"


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001
    markdown = with_sibling_source(markdown, page.file.src_uri)
    if not any(k in markdown for k in ("result-source", "result-table", "no-result-file", "{{")):
        return markdown
    try:
        return render(markdown, page.file.src_uri)
    except ResultError as e:
        raise ResultError(f"{page.file.src_uri}: {e}") from None
