"""A robot's model and its sources: its ``robots/<robot>/README.md`` as HTML.

The README is rendered with ``markdown-it-py`` (installed with ``rich``), with raw HTML
disabled; without it, the text is shown preformatted.
"""

from __future__ import annotations

import html
from pathlib import Path

from walkrepro.locations import ROBOTS_DIR


def robot_readme(robot: str) -> Path | None:
    """``robots/<robot>/README.md``, if there is one."""
    path = ROBOTS_DIR / robot / "README.md"
    return path if path.is_file() else None


def markdown_to_html(text: str) -> str:
    """Markdown (CommonMark with tables) to an HTML fragment; raw HTML in the text is
    escaped. Preformatted text if ``markdown-it-py`` is not installed."""
    try:
        from markdown_it import MarkdownIt
    except ImportError:
        return f"<pre>{html.escape(text)}</pre>"
    return MarkdownIt("commonmark", {"html": False}).enable("table").render(text)
