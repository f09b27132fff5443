"""Pastes generated tables into the README and the ``docs/`` pages between markers (never by
hand).

A block ``<!-- BEGIN:name -->`` ... ``<!-- END:name -->`` is replaced by ``results/name.md``.
"""

from __future__ import annotations

import re
from pathlib import Path

from mfcl_jax.io.atomic import atomic_write

__all__ = ["update_readme", "update_docs", "update_block"]

_BLOCK = re.compile(r"(<!-- BEGIN:([\w/.-]+) -->\n)(.*?)(<!-- END:\2 -->)", re.S)


def update_readme(readme="README.md", results="results") -> list[str]:
    """Refreshes every marked block of one Markdown file whose table exists; returns the
    names refreshed."""
    results = Path(results)
    return _fill(readme, lambda name: results / f"{name}.md")


def update_block(page, name: str, table) -> bool:
    """Refreshes only the block ``name`` of ``page`` with the Markdown file ``table`` (a
    benchmark pasting its own table); whether the block was there."""
    return name in _fill(page, lambda n: Path(table) if n == name else None)


def _fill(readme, source) -> list[str]:
    """Replaces each block whose ``source(name)`` file exists; the names replaced."""
    readme = Path(readme)
    if not readme.exists():
        return []
    text = readme.read_text()
    done = []

    def fill(m):
        src = source(m.group(2))
        if src is None or not src.exists():
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
