"""The ``--progress`` flag shared by the commands that take long."""

from __future__ import annotations

__all__ = ["add_progress_flag"]


def add_progress_flag(parser) -> None:
    parser.add_argument(
        "--progress",
        action="store_true",
        help="progress messages on stderr even when it is not a terminal (default: only then)",
    )
