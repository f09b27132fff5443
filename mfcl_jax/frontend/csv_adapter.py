"""Candidates from another front-end, read from CSV (``submap, x, y, yaw_deg, score``)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from mfcl_jax import se2
from mfcl_jax.frontend.candidates import Candidates

__all__ = ["load_candidates_csv"]


_CSV_FIELDS = ("submap", "x", "y", "yaw_deg", "score")


def load_candidates_csv(path, n_submaps: int, J: int) -> Candidates:
    """Reads candidates from an external front-end.

    The CSV has a header with at least ``submap, x, y, yaw_deg, score``; one row per candidate
    (``submap`` is the 0-based row of the ``SubmapBatch``). Each submap keeps its ``J``
    highest-scoring rows; submaps without rows get reason 3 ("no features").

    Raises:
        ValueError: naming the file, line and field of the first bad value.
    """
    path = Path(path)
    per: list[list[tuple[float, float, float, float]]] = [[] for _ in range(n_submaps)]
    with path.open(newline="") as fh:
        reader = csv.DictReader(fh)
        missing = [f for f in _CSV_FIELDS if f not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(
                f"{path}: line 1: missing column(s) {missing}; need {list(_CSV_FIELDS)}"
            )
        for row in reader:
            line = reader.line_num
            vals = {}
            for f in _CSV_FIELDS:
                raw = row.get(f)
                try:
                    v = int(raw) if f == "submap" else float(raw)
                except (TypeError, ValueError):
                    msg = f"{path}: line {line}: field {f!r}: bad value {raw!r}"
                    raise ValueError(msg) from None
                if f != "submap" and not math.isfinite(v):
                    raise ValueError(f"{path}: line {line}: field {f!r}: non-finite value {raw!r}")
                vals[f] = v
            if not 0 <= vals["submap"] < n_submaps:
                raise ValueError(
                    f"{path}: line {line}: field 'submap': {vals['submap']} not in [0, {n_submaps})"
                )
            per[vals["submap"]].append(
                (vals["score"], vals["x"], vals["y"], math.radians(vals["yaw_deg"]))
            )
    pose = np.zeros((n_submaps, J, 3), np.float32)
    score = np.full((n_submaps, J), -np.inf, np.float32)
    mask = np.zeros((n_submaps, J), bool)
    for i, rows in enumerate(per):
        rows.sort(key=lambda r: -r[0])
        for j, (s, x, y, th) in enumerate(rows[:J]):
            pose[i, j] = (x, y, float(se2.wrap(th)))
            score[i, j] = s
            mask[i, j] = True
    reason = np.where(mask.any(1), 0, 3).astype(np.int32)
    return Candidates(pose=pose, score=score, mask=mask, reason=reason)
