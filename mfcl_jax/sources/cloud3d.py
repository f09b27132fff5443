"""A 3-D LiDAR cloud turned into the planar scan the localizer uses: a horizontal height band.

A floor plan is a horizontal section (the IFC loader cuts at 1.0 m above the storey); a 3-D
cloud is not. Projecting a whole cloud onto x, y turns the floor and the ceiling (half the
points of a Livox Mid-360 indoors) into discs of fake "walls". ``slice_cloud`` keeps the
points of a height band instead:

1. ``mount`` (optional): the sensor's pose on the robot, a 3-D rigid transform applied first,
   so that a tilted mount still gives a horizontal slice and the points land in the base
   frame the odometry describes;
2. the floor (``floor.detect_floor``): the lowest dense horizontal layer below the sensor,
   robust to a tilt of up to 10 deg. With ``relative_to="floor"`` the cloud is levelled on it
   (the rotation taking its normal to +z) and heights count from it; the ceiling is the
   highest dense layer above the sensor;
3. the band and the floor/ceiling margins select the points; their x, y are the scan.

Default band: 0.9-1.8 m above the detected floor. It holds the plan's 1.0 m section height;
it stays above desks and tables (0.72-0.76 m), seats and most chair backs, and below door
heads (2.0-2.1 m: a slice through a lintel would close the door gaps the plan draws open),
ceiling lamps and the ceiling. Relative to the floor, not the sensor, it is the same slice of
the building whether the LiDAR rides at 0.3 m on a small robot or at 1.2-1.5 m in a hand: a
Mid-360 at 0.5 m sees it on every wall farther than 0.3 m (its beams climb to 52 deg), a
handheld one all round. A spinning LiDAR with a narrow field low on a robot (a VLP-16, +-15
deg, at 0.5 m) sees it only on walls farther than 1.5 m; for it a band around the sensor
height (``relative_to="sensor"``, e.g. -0.3..0.3 m) keeps the near walls. All heights, the
margins and the detector's settings are parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.sources.floor import (
    Plane,
    PlaneParams,
    detect_ceiling,
    detect_floor,
    level_rotation,
    rowwise,
)

__all__ = [
    "BandParams",
    "Mount",
    "Plane",
    "PlaneParams",
    "SliceInfo",
    "detect_floor",
    "median_floor",
    "slice_cloud",
    "slice_clouds",
]


@dataclass(frozen=True)
class BandParams:
    """Which points of a 3-D cloud make the planar scan.

    Attributes:
        z_min, z_max: the band (m), heights above the detected floor (``relative_to="floor"``)
            or z in the (mounted) sensor frame (``relative_to="sensor"``).
        relative_to: ``"floor"`` or ``"sensor"``.
        floor_margin: points less than this above the detected floor are dropped (m).
        ceiling_margin: points less than this below the detected ceiling are dropped (m).
        planes: the floor and ceiling detectors' settings.
    """

    z_min: float = 0.9
    z_max: float = 1.8
    relative_to: str = "floor"
    floor_margin: float = 0.15
    ceiling_margin: float = 0.15
    planes: PlaneParams = field(default_factory=PlaneParams)

    def __post_init__(self):
        if self.relative_to not in ("floor", "sensor"):
            raise DataError(
                f"BandParams.relative_to must be 'floor' or 'sensor', got {self.relative_to!r}"
            )
        if not (np.isfinite(self.z_min) and np.isfinite(self.z_max) and self.z_min < self.z_max):
            raise DataError(
                f"BandParams: the band needs finite z_min < z_max, got z_min={self.z_min!r}, "
                f"z_max={self.z_max!r}"
            )
        for name in ("floor_margin", "ceiling_margin"):
            if not getattr(self, name) >= 0:
                raise DataError(f"BandParams.{name} must be >= 0, got {getattr(self, name)!r}")

    def describe(self) -> str:
        where = "above the floor" if self.relative_to == "floor" else "in the sensor frame"
        return f"z in [{self.z_min:.2f}, {self.z_max:.2f}] m {where}"


@dataclass(frozen=True)
class Mount:
    """Pose of the sensor on the robot base: ``p_base = R p_sensor + xyz``.

    Attributes:
        xyz: translation (m).
        rpy: roll, pitch, yaw (rad); ``R = Rz(yaw) Ry(pitch) Rx(roll)``, as a ROS
            ``/tf_static`` transform from the base to the sensor frame.
    """

    xyz: tuple = (0.0, 0.0, 0.0)
    rpy: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        for name in ("xyz", "rpy"):
            v = np.asarray(getattr(self, name), np.float64)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise DataError(f"Mount.{name} needs 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(x) for x in v))

    def matrix(self) -> np.ndarray:
        """``(3, 3)`` rotation."""
        r, p, y = (float(v) for v in self.rpy)
        rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
        ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
        rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
        return rz @ ry @ rx

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Sensor-frame points ``(n, 3)`` -> base frame."""
        return rowwise(points, self.matrix()) + np.asarray(self.xyz, np.float64)


@dataclass(frozen=True)
class SliceInfo:
    """What ``slice_cloud`` did.

    Attributes:
        band: the band's description.
        floor: the detected (or given) floor, ``None`` when there was none.
        ceiling: height of the detected ceiling above the floor (or in the frame), or ``None``.
        n_points: finite points in the cloud.
        n_floor, n_ceiling: points dropped by the floor / ceiling margins.
        n_kept: points in the scan.
        z_range: ``(min, max)`` of the heights the band was applied to.
    """

    band: str
    floor: Plane | None
    ceiling: float | None
    n_points: int
    n_floor: int
    n_ceiling: int
    n_kept: int
    z_range: tuple


def _finite_cloud(points, where: str) -> np.ndarray:
    """The finite rows of an ``(n, 3)`` cloud as float64; ``DataError`` for another shape."""
    p = np.asarray(points, np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise DataError(f"{where}: a 3-D cloud must be (n, 3), got shape {p.shape}")
    return p[np.all(np.isfinite(p), 1)]


def slice_cloud(
    points_xyz,
    params: BandParams = BandParams(),
    mount: Mount | None = None,
    floor: Plane | None = None,
    where: str = "<cloud>",
):
    """The planar scan of one 3-D cloud.

    Args:
        points_xyz: ``(n, 3)`` points in the sensor frame (NaN rows are no-returns, dropped).
        params: the band and the floor/ceiling detection.
        mount: sensor pose on the base (applied first); ``None``: the sensor frame is the base.
        floor: a floor plane known in advance (in the mounted frame); ``None``: detect it.
        where: the cloud's name, for messages.

    Returns:
        ``(points_xy (m, 2), SliceInfo)``: x, y of the kept points in the (mounted and, with
        ``relative_to="floor"``, levelled) frame.

    Raises:
        DataError: the array is not ``(n, 3)``; ``relative_to="floor"`` and no floor below the
            sensor; no point in the band (the message names the band and the heights present).
    """
    p = _finite_cloud(points_xyz, where)
    if mount is not None:
        p = mount.apply(p)
    if floor is None:
        floor = detect_floor(p, params.planes)
    if floor is None and params.relative_to == "floor":
        zr = f"[{p[:, 2].min():.2f}, {p[:, 2].max():.2f}] m" if len(p) else "none"
        raise DataError(
            f"{where}: no floor plane below the sensor ({len(p)} points, z in {zr}); "
            "give the floor (or a mount) or use a band relative to the sensor"
        )
    low = np.zeros(len(p), bool)
    if floor is not None:
        low = rowwise(p, floor.normal) + floor.height < params.floor_margin
    if params.relative_to == "floor":
        p = rowwise(p, level_rotation(floor.normal))
        up = p[:, 2] + floor.height
        ceiling = detect_ceiling(p, up, floor.height, params.planes)
    else:
        up = p[:, 2]
        ceiling = detect_ceiling(p, up, 0.0, params.planes)
    high = up > ceiling - params.ceiling_margin if ceiling is not None else np.zeros_like(low)
    band = (up >= params.z_min) & (up <= params.z_max)
    keep = band & ~low & ~high
    zr = (float(up.min()), float(up.max())) if len(up) else (float("nan"), float("nan"))
    if not keep.any():
        raise DataError(
            f"{where}: no point in the band {params.describe()} (after the floor/ceiling "
            f"margins); the cloud's {len(p)} points span z in [{zr[0]:.2f}, {zr[1]:.2f}] m"
        )
    info = SliceInfo(
        band=params.describe(),
        floor=floor,
        ceiling=ceiling,
        n_points=len(p),
        n_floor=int(np.sum(band & low)),
        n_ceiling=int(np.sum(band & high & ~low)),
        n_kept=int(keep.sum()),
        z_range=zr,
    )
    return p[keep, :2], info


def median_floor(planes) -> Plane | None:
    """The median of detected floors (``None`` entries skipped; ``None`` when none is left):
    what a rigidly mounted sensor's clouds share (see ``slice_clouds``)."""
    found = [f for f in planes if f is not None]
    if not found:
        return None
    n = np.median([f.normal for f in found], axis=0)
    h = float(np.median([f.height for f in found]))
    return Plane(n / np.linalg.norm(n), h, int(np.median([f.n_points for f in found])))


def slice_clouds(
    clouds,
    params: BandParams = BandParams(),
    mount: Mount | None = None,
    rigid: bool = True,
    where: str = "<clouds>",
    names=None,
):
    """The planar scans of a sequence of clouds from one sensor.

    The floor is detected in every cloud. ``rigid`` (a sensor bolted to a wheeled robot on a
    flat floor): the floor sits at the same place in every cloud, so every cloud is sliced on
    the median of the detected floors, which outvotes the few clouds whose floor is barely
    visible (a low sensor in a small room or a corridor sees the floor only far away, if at
    all). Otherwise (handheld) each cloud uses its own floor, and a cloud without one uses the
    median.

    Args:
        clouds: ``N`` arrays ``(n_i, 3)`` (or one ``(N, n, 3)`` array with NaN rows).
        params, mount: as ``slice_cloud``.
        rigid: share one floor (see above).
        where: the sequence's name, for messages.
        names: ``N`` names of the clouds for messages (scan files, stamps); default
            ``"{where} cloud #i"``.

    Returns:
        ``(scans, infos, detected)``: ``N`` arrays ``(m_i, 2)``, ``N`` ``SliceInfo`` (their
        ``floor`` is the plane used) and the ``N`` per-cloud detections (``Plane`` or
        ``None``).

    Raises:
        DataError: no cloud shows a floor (with ``relative_to="floor"``), or a cloud has no
            point in the band (named by ``names`` or its index).
    """
    names = [f"{where} cloud #{i}" for i in range(len(clouds))] if names is None else names
    mounted = [_finite_cloud(c, n) for c, n in zip(clouds, names, strict=True)]
    if mount is not None:
        mounted = [mount.apply(c) for c in mounted]
    detected = [detect_floor(c, params.planes) for c in mounted]
    shared = median_floor(detected)
    if shared is None and params.relative_to == "floor":
        raise DataError(
            f"{where}: no floor plane below the sensor in any of the {len(mounted)} clouds; "
            "use a band relative to the sensor"
        )
    scans, infos = [], []
    for c, f, name in zip(mounted, detected, names, strict=True):
        use = shared if rigid or f is None else f
        xy, info = slice_cloud(c, params, floor=use, where=name)
        scans.append(xy)
        infos.append(info)
    return scans, infos, detected
