"""The one scorer: the only code that reads ground truth (placement errors, run summaries,
identifiability labels)."""

from mfcl_jax.score.decisions import (
    decisions_frame,
    format_table,
    pose_at,
    score_batch,
    score_decisions,
    score_rows,
    summarize,
)
from mfcl_jax.score.summary import CORRECT_XY, CORRECT_YAW_DEG, first_commits, wilson

__all__ = [
    "CORRECT_XY",
    "CORRECT_YAW_DEG",
    "decisions_frame",
    "first_commits",
    "format_table",
    "pose_at",
    "score_batch",
    "score_decisions",
    "score_rows",
    "summarize",
    "wilson",
]
