"""MkDocs hook: the table of the chain's signals, from ``ftdrake.conventions`` at build time.

``<!-- ftdrake-signals -->`` in a page becomes
:func:`ftdrake.conventions.signal_table_markdown`: every output port of the runtime chain
with its log column(s), its LCM channel and its ROS 2 topic, as the code names them, so the
page never disagrees with the logs and the stations.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MARKER = "<!-- ftdrake-signals -->"


def signal_table() -> str:
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from ftdrake.conventions import signal_table_markdown  # noqa: PLC0415 (after the path)

    return signal_table_markdown()


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001
    return markdown.replace(MARKER, signal_table()) if MARKER in markdown else markdown
