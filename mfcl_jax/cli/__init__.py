"""The ``mfcl`` command (a thin shell: each command calls one package function).

Importing this module and ``mfcl --help`` load nothing heavy (JAX, matplotlib, SciPy,
pandas, rosbags, IfcOpenShell): each command imports what it needs when it runs.
"""

from __future__ import annotations

import argparse
import sys

from mfcl_jax.cli.evaluate import add_evaluate_command
from mfcl_jax.cli.floorplan import add_floorplan_commands
from mfcl_jax.cli.localize import add_localize_command
from mfcl_jax.cli.ros2 import add_ros2_commands
from mfcl_jax.cli.simulate import add_simulate_command

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mfcl", description="Move First, Commit Later: LiDAR-to-BIM global initialization"
    )
    sub = parser.add_subparsers(dest="command", required=True)
    add_floorplan_commands(sub)
    add_localize_command(sub)
    add_evaluate_command(sub)
    add_simulate_command(sub)
    add_ros2_commands(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"mfcl: warning: {message}", file=sys.stderr)


def main(argv=None) -> int:
    """Entry point; bad inputs (and unwritable outputs) end with a one-line message and exit
    status 2, no traceback; warnings print as ``mfcl: warning: ...`` lines on stderr."""
    import warnings

    args = build_parser().parse_args(argv)
    from mfcl_jax.floorplan.model import FloorplanError
    from mfcl_jax.io.errors import DataError
    from mfcl_jax.robot.signals import exit_on_signal

    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        try:
            return int(args.func(args) or 0)
        except (FloorplanError, DataError, OSError) as e:
            print(f"mfcl: error: {e}", file=sys.stderr)
            return 2
        finally:
            if argv is None:  # the process's own command: its shutdown is not interrupted
                exit_on_signal()


if __name__ == "__main__":
    sys.exit(main())
