"""Windows: a scan sequence cut into submaps, the one place where that happens.

``submaps`` cuts (keyframes, sliding windows over travelled distance, submaps in the frame
of each window's last scan; ``Cutter`` as windows complete), ``odometry`` refines the
keyframe poses by LiDAR scan matching, ``padding`` lays many runs' windows into one padded
``WindowBatch`` of the arrays in ``arrays``.
"""

from mfcl_jax.windows.arrays import (
    EVIDENCE_POINTS,
    Evidence,
    RunBatch,
    SubmapBatch,
    bucket,
    end_sample,
    evidence_sample,
    pad_submaps,
)
from mfcl_jax.windows.cutters import Cutter, cut_many
from mfcl_jax.windows.icp import ScanMatchParams
from mfcl_jax.windows.keyframes import (
    keyframes,
    odometry_segments,
    segment_bounds,
    travelled,
    window_bounds,
)
from mfcl_jax.windows.odometry import Odometer
from mfcl_jax.windows.padding import WindowBatch, concat, pack
from mfcl_jax.windows.submaps import (
    WindowParams,
    Windows,
    build_submap,
    cut,
    keyframe_odometry,
    rethinned,
    window,
)

__all__ = [
    "EVIDENCE_POINTS",
    "Cutter",
    "Evidence",
    "Odometer",
    "RunBatch",
    "ScanMatchParams",
    "SubmapBatch",
    "WindowBatch",
    "WindowParams",
    "Windows",
    "bucket",
    "build_submap",
    "concat",
    "cut",
    "cut_many",
    "end_sample",
    "evidence_sample",
    "keyframe_odometry",
    "keyframes",
    "odometry_segments",
    "pad_submaps",
    "pack",
    "rethinned",
    "segment_bounds",
    "travelled",
    "window",
    "window_bounds",
]
