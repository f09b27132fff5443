"""A recording: what one run of the robot gives the localizer, plus what only the scorer sees.

Every input (built-in scene, procedural building, IFC walk, dataset folder, ROS bag, CARMEN
log) becomes a ``Recording``: the floor plan the robot is given, its ``ScanSequence`` (scans in
the sensor frame and odometry in L), and optionally the ``GroundTruth`` (true sensor poses in
B). The front-end and the decision layer receive ``floorplan`` and ``seq`` only; ``truth`` is
read by the scorer (``mfcl_jax.score``) and nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.sources.sequence import ScanSequence

__all__ = ["GroundTruth", "Recording"]


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """True sensor poses in the floor-plan frame B (scoring only).

    Attributes:
        times: ``(M,)`` increasing times (s), on the same clock as the scan sequence.
        poses: ``(M, 3)`` true sensor poses ``^B T_t``.
        source: where it came from (for messages).
    """

    times: np.ndarray
    poses: np.ndarray
    source: str = "<memory>"

    def __post_init__(self):
        t = np.asarray(self.times, np.float64).reshape(-1)
        p = np.asarray(self.poses, np.float64).reshape(-1, 3)
        if len(t) != len(p) or len(t) == 0:
            raise DataError(f"{self.source}: {len(t)} ground-truth times but {len(p)} poses")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
            raise DataError(f"{self.source}: non-finite ground-truth time or pose")
        if np.any(np.diff(t) <= 0):
            bad = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
            raise DataError(f"{self.source}: ground-truth times must increase (line #{bad})")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "poses", p)


@dataclass(frozen=True, eq=False)
class Recording:
    """One run: the floor plan, the scans with odometry, optional ground truth.

    Attributes:
        name: a unique, file-name-safe identifier (e.g. ``"office/seed3/walk1"``).
        floorplan: the ``Floorplan`` the robot is given (frame B).
        seq: the ``ScanSequence`` (what the localizer sees besides the floor plan).
        truth: ``GroundTruth`` or ``None`` (never passed to the front-end or decision layer).
        meta: free-form labels for tables (family, seed, trajectory, fault, level, ...).
    """

    name: str
    floorplan: object
    seq: ScanSequence
    truth: GroundTruth | None = None
    meta: dict = field(default_factory=dict)
