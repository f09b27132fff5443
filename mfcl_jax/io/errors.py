"""The one error type of the input/output layer."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["DataError", "atomic_write_text"]


class DataError(ValueError):
    """Unusable input data; the message names the file (and line or field) and the problem."""


def atomic_write_text(path, text: str) -> Path:
    """Writes ``text`` to ``path`` through a temporary file renamed into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
