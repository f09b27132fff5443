"""The three ways ``mfcl localize`` runs: one input streamed window by window
(``run_one``), many datasets in one batch (``run_many``), and ``--follow`` (a folder being
written, ``run_follow``); what they share is in ``common``.

Each checks its outputs before it reads anything, reads and computes everything before it
writes, and prints: per-window status lines (``robot.status.status_line``), notes on stderr,
progress on stderr when a person watches (``robot.progress.Progress``).
"""

from __future__ import annotations

from mfcl_jax.cli.run_follow import follow
from mfcl_jax.cli.run_many import localize_many
from mfcl_jax.cli.run_one import localize_one
from mfcl_jax.io.errors import DataError
from mfcl_jax.robot.progress import Progress

__all__ = ["localize", "localize_one", "localize_many", "follow"]


def localize(args, progress: Progress) -> int:
    """``mfcl localize``: checks the flags and runs the matching mode."""
    from mfcl_jax.cli.inputs import dataset_folders

    if not args.d_s > 0:
        raise DataError(f"localize: --d-s must be > 0, got {args.d_s}")
    if args.out is not None and args.out_dir is not None:
        raise DataError(f"localize: give --out ({args.out}) or --out-dir ({args.out_dir})")
    if args.follow is not None:
        return follow(args, progress)
    folders = dataset_folders(args)
    if len(folders) > 1:
        return localize_many(args, folders, progress)
    return localize_one(args, folders, progress)
