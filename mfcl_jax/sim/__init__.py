"""Simulator pieces: a planar ray-cast LiDAR, sampled walks and drifting odometry.

``mfcl_jax.sources.simulated.simulate`` plays them through a scene and returns recordings;
windows are cut from those like from any other input (``mfcl_jax.windows``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mfcl_jax.sim.raycast import LidarParams, beam_angles, cast, cast_kernel, scan_points
from mfcl_jax.sim.trajectory import Path, TrajectoryParams, odometry, sample_path

__all__ = [
    "SimParams",
    "LidarParams",
    "TrajectoryParams",
    "Path",
    "cast",
    "cast_kernel",
    "beam_angles",
    "scan_points",
    "sample_path",
    "odometry",
]


@dataclass(frozen=True)
class SimParams:
    """All simulator settings (each part documents its defaults).

    Attributes:
        lidar: the planar LiDAR (Livox Mid-360 ring: 720 beams, 40 m, 2 cm, 2 % dropout).
        trajectory: scan spacing 0.25 m, 0.5 m/s, odometry drift 0.5 % and 0.1 deg/m.
        anchor: the hidden ``^B T_L`` as ``(x, y, theta)``; ``None`` puts L at the true start
            pose of each run (odometry then starts at the identity, as an LIO does).
        restart_at: fraction of the path at which the odometry restarts from the identity
            (a fault: the frames before and after are unrelated); ``None``: no restart.
        odom_latency: seconds by which the odometry lags the scans (a fault: each scan's
            odometry pose is the one of that many seconds before it, as when the odometry's
            time stamps are late); 0: none.
    """

    lidar: LidarParams = field(default_factory=LidarParams)
    trajectory: TrajectoryParams = field(default_factory=TrajectoryParams)
    anchor: tuple[float, float, float] | None = None
    restart_at: float | None = None
    odom_latency: float = 0.0

    def __post_init__(self):
        if not 0.0 <= self.odom_latency < 5.0:
            raise ValueError(
                f"SimParams.odom_latency must be in [0, 5) s, got {self.odom_latency!r}"
            )
        if self.restart_at is not None and not 0 < self.restart_at < 1:
            raise ValueError(f"SimParams.restart_at must be in (0, 1), got {self.restart_at!r}")
