"""What the three ways ``mfcl localize`` runs share: the localization settings from the
flags, the start (JAX, the compilation cache), the ``--viz`` check and writer, and the lines
printed at the end."""

from __future__ import annotations

import sys
from pathlib import Path

from mfcl_jax.io.errors import DataError
from mfcl_jax.robot.progress import Progress

__all__ = [
    "localize_params",
    "start",
    "err",
    "check_viz",
    "summary",
    "verdict",
    "stopped",
    "split_note",
    "viz_add",
]


def localize_params(args):
    from dataclasses import replace

    from mfcl_jax.robot.localizer import LocalizeParams

    p = LocalizeParams().with_d_s(args.d_s)
    if getattr(args, "early_commit", None) is not None:
        from mfcl_jax.decision.lanes import UNIQUE_LANES

        e = args.early_commit
        p = replace(p, policy="ours_grid" if e == "grid" else UNIQUE_LANES[e])
    if getattr(args, "no_scan_match", False):
        sm = replace(p.window.scan_match, enabled=False)
        p = replace(p, window=replace(p.window, scan_match=sm))
    return p


def start(progress: Progress) -> None:
    """Imports JAX and the localizer and turns the compilation cache on."""
    with progress.stage("starting (loading JAX)"):
        import mfcl_jax.robot.localizer  # noqa: F401  (the slow imports, inside the stage)
        from mfcl_jax.robot.compile_cache import enable_cache

        enable_cache()


def err(text: str) -> None:
    print(text, file=sys.stderr)


def check_viz(path: Path, inputs) -> None:
    """``--viz``: an ``.mcap`` name that is none of the run's inputs and outputs and can be
    written (checked before any work, like the decisions file)."""
    from mfcl_jax.io import check_output

    if path.suffix.lower() != ".mcap":
        raise DataError(f"{path}: --viz writes an MCAP file; give a name ending in .mcap")
    check_output(path, inputs=inputs)


def summary(records) -> tuple[int | None, str | None]:
    first = next((d["k"] for d in records if d["state"] == "COMMIT"), None)
    return first, records[-1]["state"] if records else None


def verdict(records) -> str:
    """``"8 windows in 2 odometry segments, first COMMIT at window 3, final state DEFER"``."""
    k, last = summary(records)
    n_seg = len({d.get("segment", 0) for d in records})
    segs = f" in {n_seg} odometry segments" if n_seg > 1 else ""
    verdict = f"first COMMIT at window {k}" if k else "no commit"
    return f"{len(records)} windows{segs}, {verdict}, final state {last or 'none'}"


def stopped(stop, what: str) -> None:
    from mfcl_jax.robot.signals import stop_name, stop_status

    err(f"mfcl: stopped by {stop_name(stop)}: {what}; exit status {stop_status(stop)}")


def split_note(line: str | None) -> None:
    """A split note on stderr, after the status lines printed so far."""
    if line:
        sys.stdout.flush()
        err(line)


def viz_add(viz, result, record):
    """Adds a window to a live run's viz file; a window the file cannot hold (a time < 0)
    drops the file with a warning, and the run goes on deciding."""
    if viz is None:
        return None
    try:
        viz.add(result, record)
    except DataError as e:
        what = "the live view stops" if viz.path is None else f"{viz.path} will not be written"
        err(f"mfcl: warning: {e}; {what}")
        viz.discard()
        return None
    return viz
