"""What a feed reads (``FeedParams``: topics, frames, mounting, QoS) and what it keeps of
each topic's stamps (``Stream``: the newest, the epoch, the late ones)."""

from __future__ import annotations

from dataclasses import dataclass, field

from mfcl_jax.sources.planar import PlanarParams

__all__ = ["FeedParams", "Stream", "JUMP_S"]

JUMP_S = 1.0  # a stamp this much older than its stream's newest: the stream started again


@dataclass(frozen=True)
class FeedParams:
    """Which topics and frames the feed reads.

    Attributes:
        scan_topic: the scan topic; ``cloud``: it carries ``PointCloud2`` (else LaserScan).
        odom_topic: ``nav_msgs/Odometry`` topic, or ``/tf`` (then ``odom_frames``).
        odom_frames: ``(odom, base)`` frames of the odometry transform on ``/tf``.
        base_frame: the robot's base (the ``/tf_static`` chain starts there).
        mount: the LiDAR's planar pose ``(x, y, yaw)`` on the base, or ``None``: read it
            from ``/tf_static``.
        planar: how scans become planar (2-D, 3-D band, the mount's height and tilt).
        silence_s: seconds without messages on a topic before it is called silent.
        reliable: read the scans and odometry reliably (``dds.STREAM``; the writers must be
            reliable) instead of best effort (``dds.SENSOR``, the default: any writer).
    """

    scan_topic: str = "/scan"
    cloud: bool = False
    odom_topic: str = "/odom"
    odom_frames: tuple[str, str] = ("odom", "base_link")
    base_frame: str = "base_link"
    mount: tuple[float, float, float] | None = None
    planar: PlanarParams = field(default_factory=PlanarParams)
    silence_s: float = 5.0
    tf_static_topic: str = "/tf_static"
    reliable: bool = False


class Stream:
    """Stamps of one topic: its newest stamp, its epoch (+1 at each backward jump)."""

    def __init__(self):
        self.newest: float | None = None
        self.epoch = 0
        self.late = 0
        self.heard = None  # wall time of the last message

    def tag(self, t: float, now: float) -> int | None:
        """The epoch of a message stamped ``t``, or None when it is late."""
        self.heard = now
        if self.newest is not None and t < self.newest - JUMP_S:
            self.epoch += 1
        elif self.newest is not None and t <= self.newest:
            self.late += 1
            return None
        self.newest = t
        return self.epoch
