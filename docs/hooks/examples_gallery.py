"""MkDocs hook: the examples gallery, from ``examples/*.py`` at build time.

``<!-- ftdrake-examples -->`` in a page becomes, for every example script, a section with its
docstring (what it shows and how to run it) and its whole source, so the page always shows
the code the tests run.
"""

from __future__ import annotations

import ast
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
MARKER = "<!-- ftdrake-examples -->"


def gallery() -> str:
    parts = []
    for path in sorted(EXAMPLES.glob("*.py")):
        source = path.read_text(encoding="utf-8")
        doc = ast.get_docstring(ast.parse(source)) or ""
        title, _, body = doc.partition("\n")
        parts.append(f"## `{path.name}`\n\n{title}\n\n```text\n{body.strip()}\n```\n\n"
                     f'??? example "The source of {path.name}"\n\n'
                     + "\n".join(f"    {line}" if line else "" for line in
                                 ["```python", *source.rstrip().splitlines(), "```"]) + "\n")
    return "\n".join(parts)


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001
    return markdown.replace(MARKER, gallery()) if MARKER in markdown else markdown
