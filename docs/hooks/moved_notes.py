"""MkDocs hook: the notes moved out of the code, included where a page asks for them.

Derivations, measured figures and history taken out of docstrings live in
``docs/_moved/*.md`` (one file per topic; the folder is not built on its own). A page writes
``<!-- ftdrake-moved-notes -->`` where they belong: the marker becomes every such file, in
name order, each under a heading (its own first ``#`` heading, or its file name), with its
headings shifted one level down. No file there: a sentence saying so.
"""

from __future__ import annotations

import re
from pathlib import Path

MOVED = Path(__file__).resolve().parents[1] / "_moved"
MARKER = "<!-- ftdrake-moved-notes -->"


def notes() -> list[tuple[str, str, str]]:
    """(file name, title, body) of every docs/_moved/*.md."""
    found = []
    for path in sorted(MOVED.glob("*.md")):
        text = path.read_text(encoding="utf-8").strip()
        first = re.match(r"#\s+(.+)\n?", text)
        title = first.group(1).strip() if first else path.stem.replace("_", " ").capitalize()
        body = text[first.end():] if first else text
        found.append((path.name, title, body))
    return found


def _shifted(body: str) -> str:
    """Headings one level down, outside fenced code."""
    out, fence = [], False
    for line in body.splitlines():
        if line.lstrip().startswith("```"):
            fence = not fence
        out.append("#" + line if not fence and re.match(r"#{1,5}\s", line) else line)
    return "\n".join(out)


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001
    if MARKER not in markdown:
        return markdown
    found = notes()
    if not found:
        text = "*No notes have been moved here yet (`docs/_moved/` holds none).*\n"
    else:
        text = "\n\n".join(f"## {title}\n\n<small>`docs/_moved/{name}`</small>\n\n"
                           f"{_shifted(body)}\n" for name, title, body in found)
    return markdown.replace(MARKER, text)
