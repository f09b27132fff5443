"""The ``mfcl`` command (a thin shell: each command calls one package function)."""

from __future__ import annotations

import argparse
import sys

from mfcl_jax.cli_floorplan import add_floorplan_commands
from mfcl_jax.cli_localize import add_localize_commands

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mfcl", description="Move First, Commit Later: LiDAR-to-BIM global initialization"
    )
    sub = parser.add_subparsers(dest="command", required=True)
    add_floorplan_commands(sub)
    add_localize_commands(sub)
    return parser


def main(argv=None) -> int:
    """Entry point; bad inputs end with a one-line message and exit status 2, no traceback."""
    from mfcl_jax.floorplan.model import FloorplanError
    from mfcl_jax.io.errors import DataError

    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (FloorplanError, DataError, FileNotFoundError) as e:
        print(f"mfcl: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
