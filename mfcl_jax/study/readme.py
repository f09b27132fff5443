"""Pastes generated tables into the README and the ``docs/`` pages between markers (never by
hand).

A block ``<!-- BEGIN:name -->`` ... ``<!-- END:name -->`` is replaced by ``results/name.md``.
"""

from __future__ import annotations

import re
from pathlib import Path

from mfcl_jax.io.atomic import atomic_write

__all__ = ["update_readme", "update_docs"]

_BLOCK = re.compile(r"(<!-- BEGIN:([\w/.-]+) -->\n)(.*?)(<!-- END:\2 -->)", re.S)


def update_readme(readme="README.md", results="results") -> list[str]:
    """Refreshes every marked block of one Markdown file whose table exists; returns the
    names refreshed."""
    readme, results = Path(readme), Path(results)
    if not readme.exists():
        return []
    text = readme.read_text()
    done = []

    def fill(m):
        src = results / f"{m.group(2)}.md"
        if not src.exists():
            return m.group(0)
        done.append(m.group(2))
        return m.group(1) + src.read_text().rstrip("\n") + "\n" + m.group(4)

    new = _BLOCK.sub(fill, text)
    if new != text:
        atomic_write(readme, new)
    return done


def update_docs(results="results", root=".") -> list[str]:
    """``update_readme`` for ``README.md`` and every page under ``docs/``."""
    root = Path(root)
    pages = [root / "README.md", *sorted((root / "docs").glob("*.md"))]
    return sorted({n for page in pages for n in update_readme(page, results)})
