"""The error and warning types of the input/output layer."""

from __future__ import annotations

from pathlib import Path

from mfcl_jax.io.atomic import atomic_write

__all__ = ["DataError", "DataWarning", "atomic_write_text"]


class DataError(ValueError):
    """Unusable input data; the message names the file (and line or field) and the problem."""


class DataWarning(UserWarning):
    """Input that is usable but not exactly as written (a quaternion normalised, scans left
    out); the message names the file, what was found and what was done with it."""


def atomic_write_text(path, text: str) -> Path:
    """Writes ``text`` to ``path`` through a temporary file renamed into place."""
    return atomic_write(path, text)
