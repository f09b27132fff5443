"""``sensor_msgs/PointCloud2`` to coordinate arrays, for any driver's point layout.

The layout is read from the message, never assumed: each point is ``point_step`` bytes, a
row of ``width`` points starts every ``row_step`` bytes (``height`` rows), and each field
sits at its ``offset`` with its ``datatype`` in the byte order ``is_bigendian`` names.
Common layouts this covers (x, y, z are float32 in each):

- Livox: ``x y z intensity tag line``, packed;
- Velodyne: ``x y z intensity ring time``, with padding after z;
- Ouster: ``x y z t reflectivity ring ambient range``, with padding bytes between fields
  and a ``point_step`` larger than the fields' sum.

Points whose kept coordinates are not all finite are dropped (organised clouds, and clouds
with ``is_dense = false``, mark no-returns with NaN), and so are points exactly at the
origin (Ouster writes no-returns as zeros); both are counted, never silently kept.
"""

from __future__ import annotations

import numpy as np

from mfcl_jax.io.errors import DataError

__all__ = ["pointcloud2_points", "PC2_DATATYPES"]

PC2_DATATYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def pointcloud2_points(msg, where: str = "<PointCloud2>", xyz: bool = False):
    """The coordinates of a PointCloud2 message.

    Args:
        msg: a deserialized ``sensor_msgs/PointCloud2`` (attributes ``fields``, ``height``,
            ``width``, ``point_step``, ``row_step``, ``is_bigendian``, ``data``).
        where: the bag and topic, for messages.
        xyz: keep z (``(n, 3)``); otherwise ``(n, 2)`` and a cloud without z is accepted.

    Returns:
        ``(points (n, 2) or (n, 3) float64, n_dropped)``.

    Raises:
        DataError: a missing coordinate field (the fields present are listed), an unknown
            datatype, a field that does not fit in ``point_step``, a ``row_step`` shorter
            than a row, or data shorter than the layout needs (each names the value).
    """
    names = ("x", "y", "z") if xyz else ("x", "y")
    fields = {f.name: f for f in msg.fields}
    for name in names:
        if name not in fields:
            raise DataError(f"{where}: PointCloud2 without field {name!r} ({list(fields)})")
    h, w = int(msg.height), int(msg.width)
    step, row = int(msg.point_step), int(msg.row_step)
    end = ">" if msg.is_bigendian else "<"
    formats, offsets = [], []
    for name in names:
        f = fields[name]
        if f.datatype not in PC2_DATATYPES:
            raise DataError(f"{where}: field {name!r} has unknown datatype {f.datatype}")
        dt = np.dtype(end + PC2_DATATYPES[f.datatype])
        if f.offset + dt.itemsize > step:
            raise DataError(
                f"{where}: field {name!r} at offset {f.offset} ({dt.itemsize} bytes) does not "
                f"fit in point_step {step}"
            )
        formats.append(dt)
        offsets.append(int(f.offset))
    if h * w == 0:
        return np.zeros((0, len(names))), 0
    if row < w * step:
        raise DataError(f"{where}: row_step {row} is shorter than width {w} x point_step {step}")
    data = np.asarray(msg.data, np.uint8).reshape(-1)
    need = (h - 1) * row + w * step
    if data.size < need:
        raise DataError(
            f"{where}: data holds {data.size} bytes, height {h} x row_step {row} needs {need}"
        )
    rec = np.dtype({"names": list(names), "formats": formats, "offsets": offsets, "itemsize": step})
    if row == w * step:
        pts = np.frombuffer(data, rec, count=h * w)
    else:  # rows padded beyond their points
        pts = np.concatenate([np.frombuffer(data, rec, count=w, offset=r * row) for r in range(h)])
    out = np.stack([pts[n].astype(np.float64) for n in names], -1)
    ok = np.all(np.isfinite(out), axis=1) & np.any(out != 0.0, axis=1)
    return np.ascontiguousarray(out[ok]), int(np.count_nonzero(~ok))
