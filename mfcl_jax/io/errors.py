"""The error and warning types of the input/output layer."""

from __future__ import annotations

__all__ = ["DataError", "DataWarning"]


class DataError(ValueError):
    """Unusable input data; the message names the file (and line or field) and the problem."""


class DataWarning(UserWarning):
    """Input that is usable but not exactly as written (a quaternion normalised, scans left
    out); the message names the file, what was found and what was done with it."""
