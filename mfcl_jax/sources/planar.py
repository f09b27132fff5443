"""The planar scans of any input: 2-D scans pass through, 3-D clouds are cut by a height band.

2-D or 3-D is decided from the data unless told (``PlanarParams.dim``): a scan whose z values
span more than ``Z_SPAN_3D`` (0.3 m) is a 3-D cloud; the median span over the scans decides
for a sequence (a planar scanner's z is 0, or a few centimetres of noise on a tilted one; a
3-D LiDAR indoors sees floor and ceiling metres apart). The live path decides on the first
scan.

A 3-D cloud goes through ``cloud3d.slice_clouds`` (the band, the floor and ceiling removed,
the mount's tilt levelled). ``band=None`` (``--no-band``) projects whole clouds onto x, y as
the package did before the band existed: wrong for a 3-D sensor, whose floor and ceiling
points then draw discs of false walls (see ``results/lidar3d.md``: such runs never commit).

The mount given here is the part of the sensor's pose on the robot that the planar odometry
does not hold: its height and its roll and pitch (``mount_3d``). The planar part (x, y, yaw)
goes into the odometry (``io.tf_static.sensor_poses``), so the sliced scan is in the frame of
the planar sensor pose, levelled.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mfcl_jax.io.errors import DataError
from mfcl_jax.sources.cloud3d import (
    BandParams,
    Mount,
    detect_floor,
    median_floor,
    slice_cloud,
    slice_clouds,
)

__all__ = ["Z_SPAN_3D", "PlanarParams", "z_extent", "input_dim", "mount_3d", "planar_scans",
           "PlanarStream"]  # fmt: skip

Z_SPAN_3D = 0.3


@dataclass(frozen=True)
class PlanarParams:
    """How the scans of an input become planar scans.

    Attributes:
        dim: 2 (planar: z is ignored), 3 (clouds, cut by the band), or ``None``: decided from
            the z extent (``input_dim``).
        band: the height band, or ``None`` to project whole clouds onto x, y (``--no-band``).
        mount: the sensor's height, roll and pitch on the robot (``mount_3d``), or ``None``.
    """

    dim: int | None = None
    band: BandParams | None = field(default_factory=BandParams)
    mount: Mount | None = None

    def __post_init__(self):
        if self.dim not in (None, 2, 3):
            raise DataError(f"PlanarParams.dim must be 2, 3 or None, got {self.dim!r}")


def z_extent(scan) -> float:
    """Span ``max z - min z`` of a scan's finite points (0 for ``(n, 2)`` or empty scans)."""
    p = np.asarray(scan, np.float64)
    if p.ndim != 2 or p.shape[1] < 3:
        return 0.0
    z = p[:, 2][np.isfinite(p[:, 2])]
    return float(z.max() - z.min()) if len(z) else 0.0


def input_dim(scans) -> tuple[int, float]:
    """``(2 or 3, median z extent)`` of a sequence of scans (see the module docstring)."""
    span = float(np.median([z_extent(s) for s in scans])) if len(scans) else 0.0
    return (3 if span > Z_SPAN_3D else 2), span


def mount_3d(x, y, z, roll, pitch, yaw) -> tuple[tuple[float, float, float], Mount]:
    """Splits a sensor pose on the robot (m, rad; ``R = Rz(yaw) Ry(pitch) Rx(roll)``) into the
    planar offset ``(x, y, yaw)`` for the odometry and the ``Mount`` that levels the clouds in
    the planar sensor frame: ``Rz(-yaw) R = Ry(pitch) Rx(roll)``, raised by ``z``."""
    return (float(x), float(y), float(yaw)), Mount(xyz=(0.0, 0.0, z), rpy=(roll, pitch, 0.0))


def _project(scan) -> np.ndarray:
    p = np.asarray(scan, np.float64)
    return np.ascontiguousarray(p[:, :2]) if p.ndim == 2 and p.shape[1] >= 2 else p.reshape(-1, 2)


def planar_scans(scans, params: PlanarParams, names, where: str) -> tuple[list, list[str]]:
    """Planar scans of a whole sequence, with notes for the user.

    Args:
        scans: ``N`` arrays ``(n_i, 2)`` or ``(n_i, 3)`` in the sensor frame.
        params: ``PlanarParams``.
        names: ``N`` names for messages (scan files or stamps).
        where: the sequence's name.

    Returns:
        ``(scans (n_i', 2), notes)``.

    Raises:
        DataError: a 3-D sequence without a floor (band relative to the floor), a cloud with no
            point in the band (named by ``names``).
    """
    dim, span = input_dim(scans)
    told = params.dim is not None
    dim = params.dim or dim
    rule = "as told" if told else f"median z extent {span:.2f} m"
    if dim == 2 or params.band is None:
        notes = []
        if span > Z_SPAN_3D:
            why = "--no-band" if params.band is None else "--input-dim 2"
            notes.append(
                f"{where}: 3-D clouds (median z extent {span:.2f} m) projected whole onto x, y "
                f"({why}): floor and ceiling points become false walls"
            )
        return [_project(s) for s in scans], notes
    out, infos, detected = slice_clouds(
        [np.asarray(s, np.float64).reshape(len(s), -1) for s in scans],
        params.band,
        params.mount,
        where=where,
        names=list(names),
    )
    floor = infos[0].floor
    kept = np.median([i.n_kept for i in infos])
    total = np.median([i.n_points for i in infos])
    seen = sum(f is not None for f in detected)
    floor_text = (
        f"floor {floor.height:.2f} m below, tilt {floor.tilt_deg:.1f} deg (seen in {seen}/"
        f"{len(detected)} clouds)"
        if floor is not None
        else "no floor seen"
    )
    note = (
        f"{where}: 3-D clouds ({rule}) cut at {params.band.describe()}; {floor_text}; "
        f"median {kept:.0f} of {total:.0f} points kept"
    )
    return out, [note]


class PlanarStream:
    """Planar scans of scans that arrive one at a time (``mfcl localize --follow``).

    The first scan decides 2-D or 3-D (unless ``params.dim``). The floor of a rigidly mounted
    sensor is the median of the floors detected SO FAR (causal: the whole-sequence median of
    ``slice_clouds`` may differ slightly); clouds that come before the first detected floor
    wait for it (with a band relative to the floor).

    Args:
        params: ``PlanarParams``.
    """

    def __init__(self, params: PlanarParams):
        self.params = params
        self.dim = params.dim
        self._floors: list = []
        self._pending: list = []

    @property
    def waiting(self) -> int:
        """Clouds held until a floor is seen."""
        return len(self._pending)

    def push(self, scan, name: str) -> list:
        """Adds one scan; returns the planar scans now ready (oldest first, maybe none)."""
        if self.dim is None:
            self.dim = 3 if z_extent(scan) > Z_SPAN_3D else 2
        band = self.params.band
        if self.dim == 2 or band is None:
            return [_project(scan)]
        c = np.asarray(scan, np.float64)
        if c.ndim != 2 or c.shape[1] != 3:
            raise DataError(f"{name}: a 3-D cloud must be (n, 3), got shape {c.shape}")
        c = c[np.all(np.isfinite(c), 1)]
        if self.params.mount is not None:
            c = self.params.mount.apply(c)
        self._floors.append(detect_floor(c, band.planes))
        self._pending.append((c, name))
        floor = median_floor(self._floors)
        if floor is None and band.relative_to == "floor":
            return []
        out = [slice_cloud(p, band, floor=floor, where=n)[0] for p, n in self._pending]
        self._pending = []
        return out
