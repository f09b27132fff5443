"""Pastes generated tables into README.md between markers (never by hand).

A block ``<!-- BEGIN:name -->`` ... ``<!-- END:name -->`` is replaced by ``results/name.md``.
"""

from __future__ import annotations

import re
from pathlib import Path

from mfcl_jax.io.atomic import atomic_write

__all__ = ["update_readme"]

_BLOCK = re.compile(r"(<!-- BEGIN:([\w/.-]+) -->\n)(.*?)(<!-- END:\2 -->)", re.S)


def update_readme(readme="README.md", results="results") -> list[str]:
    """Refreshes every marked block whose table exists; returns the names refreshed."""
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
