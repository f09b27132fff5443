"""``mfcl localize``: its flags and exit codes (thin; the three ways it runs are in
``mfcl_jax.cli.runs``, the work in ``mfcl_jax.robot``). Inputs, the odometry convention and
the 3-D band: ``mfcl_jax.cli.inputs`` (flags: ``cli.flags``); what the status lines mean:
``mfcl_jax.robot.status``; ``--viz``: ``mfcl_jax.robot.viz``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mfcl_jax.cli.flags import add_input_flags
from mfcl_jax.cli.progress_flag import add_progress_flag
from mfcl_jax.robot.status import help_text

__all__ = ["add_localize_command", "cmd_localize", "EXIT_BAD_INPUT"]

EXIT_BAD_INPUT = 2  # ``mfcl_jax.cli.main``: a bad input or an output that cannot be written
# the error rates of the uniqueness lanes (``decision.lanes.UNIQUE_LANES``; a test keeps them
# in step: this module imports no JAX, so ``mfcl --help`` stays light)
EARLY_COMMIT_ALPHAS = (1e-1, 1e-2, 1e-3, 1e-4, 1e-6)


def _early_commit(value: str):
    """``--early-commit``: ``grid`` or one of ``EARLY_COMMIT_ALPHAS``."""
    if value == "grid":
        return value
    try:
        alpha = float(value)
    except ValueError:
        alpha = None
    if alpha not in EARLY_COMMIT_ALPHAS:
        raise argparse.ArgumentTypeError(
            f"{value!r} is neither 'grid' nor one of {', '.join(map(str, EARLY_COMMIT_ALPHAS))}"
        )
    return alpha


LOCALIZE_EPILOG = """\
decisions file (--out, JSON lines; one line per window):
  k is the window's index over the whole recording (it never starts again); segment is
  its odometry segment: 0, plus one after every odometry jump (a restart of the
  odometry). After a jump the decision layer starts over, and a line on stderr says
  where and why the run was split: the input odometry's step test (a step no robot
  makes) or the LiDAR odometry's jump test (a step the scans do not fit).

several datasets (a folder of dataset folders, or DATASET DATASET ...): each one's
  decisions file is written the moment it is decided (--out-dir); the datasets are
  decided by plan size, in chunks within --max-memory.

stopping: Ctrl-C (SIGINT) and SIGTERM (systemd, docker stop, timeout) stop any run the
  same way: what was decided so far is written, atomically (--out, --out-dir, --viz).

exit status:
  0    done; --follow: also when stopped by idle time, Ctrl-C or SIGTERM
  2    bad input or an output that cannot be written (several datasets: every bad one
       is named and none decided; with --keep-going the others are decided and
       written, and the exit status is still 2)
  130  one dataset or several: stopped by Ctrl-C (the windows decided so far written)
  143  the same, stopped by SIGTERM"""


def add_localize_command(subparsers) -> None:
    """Adds ``localize`` to an argparse sub-parser set."""
    lo = subparsers.add_parser(
        "localize",
        help="register submap windows to a floor plan and decide per window",
        description="Register submap windows to a floor plan and decide, window by window, "
        "whether the robot is localized (COMMIT), in a symmetric place (AMBIGUOUS) or not yet "
        "(DEFER). Status lines go to stdout, decisions to a JSON-lines file.",
        epilog=help_text() + "\n\n" + LOCALIZE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_input_flags(lo)
    lo.add_argument("--d-s", type=float, default=6.0, help="window length in metres (6)")
    lo.add_argument(
        "--early-commit",
        type=_early_commit,
        metavar="ALPHA|grid",
        help="also commit as soon as one placement explains the whole path better than every "
        "placement more than 1 m / 5 deg from it by a likelihood ratio of 1/ALPHA (the "
        "uniqueness test; ALPHA one of 0.1, 0.01, 0.001, 1e-4, 1e-6), or ('grid') where the "
        "evidence grid's leader leads every other placement by 4 nats; status lines show the "
        "ratio as L=. Earlier commits at a risk the benchmark measures (README); default: "
        "off, commit only when three windows that share no scan agree",
    )
    lo.add_argument(
        "--no-scan-match",
        action="store_true",
        help="build submaps on the input odometry as it is (default: keyframe poses refined by "
        "LiDAR scan matching first, which removes wheel-odometry drift; an LIO's odometry "
        "needs no refinement)",
    )
    lo.add_argument(
        "--out",
        type=Path,
        help="decisions JSON lines (written atomically; default decisions.jsonl; with "
        "--follow: written at the end, only when given)",
    )
    lo.add_argument(
        "--viz",
        type=Path,
        metavar="FILE.mcap",
        help="also write the run for a person to look at: an MCAP file that Foxglove opens "
        "(the plan, the scans placed at the committed anchor, the anchored path, each "
        "window's state and alternatives, on a timeline; written atomically at the end, as "
        "the decisions are; one dataset only; see mfcl_jax.robot.viz)",
    )
    lo.add_argument(
        "--out-dir",
        type=Path,
        help="one decisions file per dataset, <dataset name>.jsonl (several datasets)",
    )
    lo.add_argument(
        "--follow",
        type=Path,
        metavar="DIR",
        help="live: watch a dataset folder being written; decide as windows complete, stream "
        "the decisions as JSON lines on stdout (status on stderr); stop on Ctrl-C or idle",
    )
    lo.add_argument(
        "--idle-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="--follow: stop after S seconds without new data (10)",
    )
    lo.add_argument(
        "--keep-going",
        action="store_true",
        help="several datasets: decide the good ones when some cannot be read (they are "
        "named on stderr; exit status 2); default: name every bad one and decide none",
    )
    lo.add_argument(
        "--max-memory",
        metavar="SIZE",
        help="several datasets: the resident memory to stay within, e.g. 6G, 512M or 60%% "
        "(default: 70%% of the memory available at the start); datasets are decided in "
        "chunks that shrink when one passes it",
    )
    lo.add_argument("--quiet", action="store_true", help="no per-window status lines")
    add_progress_flag(lo)
    lo.set_defaults(func=cmd_localize)


def cmd_localize(args) -> int:
    from mfcl_jax.cli.runs import localize
    from mfcl_jax.robot.progress import Progress

    return localize(args, Progress(True if args.progress else None))
