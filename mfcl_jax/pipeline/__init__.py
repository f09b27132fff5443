"""The robot path: scan sequences -> submap windows -> front-end -> streaming decisions;
scoring against ground truth; simulated datasets; occupancy maps from logs; real-data runs."""

from mfcl_jax.pipeline.localize import LocalizeParams, Localizer, WindowResult, localize
from mfcl_jax.pipeline.score import format_table, pose_at, score_decisions, summarize
from mfcl_jax.pipeline.simdata import (
    check_waypoints,
    read_waypoints,
    simulate_dataset,
    simulate_scans,
)
from mfcl_jax.sources.sequence import (
    ScanSequence,
    from_bag,
    from_carmen,
    from_dataset,
    keyframes,
)

__all__ = [
    "LocalizeParams",
    "Localizer",
    "ScanSequence",
    "WindowResult",
    "check_waypoints",
    "format_table",
    "from_bag",
    "from_carmen",
    "from_dataset",
    "keyframes",
    "localize",
    "pose_at",
    "read_waypoints",
    "score_decisions",
    "simulate_dataset",
    "simulate_scans",
    "summarize",
]
