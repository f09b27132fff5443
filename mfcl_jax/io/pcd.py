"""PCD point clouds (ascii and binary) reduced to planar points ``(n, 2)``.

Only ``x`` and ``y`` are kept; other fields (``z``, ``intensity``, ...) are read past.
Points with a non-finite x or y are dropped and counted, never silently repaired.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mfcl_jax.io.atomic import atomic_write
from mfcl_jax.io.errors import DataError

__all__ = ["read_pcd", "write_pcd"]

_TYPES = {
    ("F", 4): "f4",
    ("F", 8): "f8",
    ("I", 1): "i1",
    ("I", 2): "i2",
    ("I", 4): "i4",
    ("I", 8): "i8",
    ("U", 1): "u1",
    ("U", 2): "u2",
    ("U", 4): "u4",
    ("U", 8): "u8",
}


def read_pcd(path, return_dropped: bool = False):
    """Reads the x, y coordinates of a PCD file.

    Args:
        path: a ``.pcd`` file, ``DATA ascii`` or ``DATA binary``.
        return_dropped: also return how many points had NaN/inf coordinates.

    Returns:
        ``points (n, 2)`` float64, or ``(points, n_dropped)``.

    Raises:
        DataError: missing file, a header without fields ``x`` and ``y`` (the fields present
            are listed), an unsupported field type or data format, or truncated data.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    header, pos = {}, 0
    while True:
        end = raw.find(b"\n", pos)
        if end < 0:
            raise DataError(f"{path}: header has no DATA line")
        line = raw[pos:end].decode("ascii", "replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, *vals = line.split()
        header[key.upper()] = vals
        if key.upper() == "DATA":
            break
    fields = header.get("FIELDS", [])
    for f in ("x", "y"):
        if f not in fields:
            raise DataError(f"{path}: missing field {f!r} (fields are {fields})")
    n_f = len(fields)
    sizes = [int(v) for v in header.get("SIZE", ["4"] * n_f)]
    types = header.get("TYPE", ["F"] * n_f)
    counts = [int(v) for v in header.get("COUNT", ["1"] * n_f)]
    if not len(sizes) == len(types) == len(counts) == n_f:
        raise DataError(f"{path}: FIELDS, SIZE, TYPE and COUNT lengths differ")
    for f, t, s in zip(fields, types, sizes, strict=True):
        if (t.upper(), s) not in _TYPES:
            raise DataError(f"{path}: field {f!r} has unsupported TYPE {t} SIZE {s}")
    n = int(header.get("POINTS", header.get("WIDTH", ["0"]))[0])
    fmt = header["DATA"][0].lower()
    ix, iy = fields.index("x"), fields.index("y")
    if fmt == "ascii":
        text = raw[pos:].decode("ascii", "replace").split()
        width = sum(counts)
        if len(text) < n * width:
            raise DataError(f"{path}: {n} points declared, ascii data holds {len(text) // width}")
        vals = np.asarray(text[: n * width], dtype=object).reshape(n, width)
        col = np.cumsum([0] + counts)
        try:
            xy = np.stack([vals[:, col[ix]].astype(float), vals[:, col[iy]].astype(float)], -1)
        except ValueError as e:
            raise DataError(f"{path}: non-numeric ascii data ({e})") from None
    elif fmt == "binary":
        dt = np.dtype(
            [
                (f"{f}_{i}", _TYPES[(t.upper(), s)], (c,) if c > 1 else ())
                for i, (f, t, s, c) in enumerate(zip(fields, types, sizes, counts, strict=True))
            ]
        )
        if len(raw) - pos < n * dt.itemsize:
            raise DataError(f"{path}: binary data truncated ({n} points declared)")
        rec = np.frombuffer(raw, dtype=dt, count=n, offset=pos)
        xy = np.stack([rec[dt.names[ix]].astype(float), rec[dt.names[iy]].astype(float)], -1)
    else:
        raise DataError(f"{path}: unsupported DATA {fmt!r} (ascii or binary)")
    xy = xy.reshape(-1, 2)
    ok = np.all(np.isfinite(xy), axis=1)
    dropped = int(np.count_nonzero(~ok))
    xy = np.ascontiguousarray(xy[ok])
    return (xy, dropped) if return_dropped else xy


def write_pcd(path, points, binary: bool = True) -> Path:
    """Writes points ``(n, 2)`` or ``(n, 3)`` as a PCD file with fields ``x y z`` (atomic).

    Raises:
        DataError: points of the wrong shape.
    """
    path = Path(path)
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise DataError(f"{path}: points must be (n, 2) or (n, 3), got {pts.shape}")
    if pts.shape[1] == 2:
        pts = np.concatenate([pts, np.zeros((len(pts), 1))], 1)
    pts = pts.astype(np.float32)
    head = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\n"
        f"SIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {len(pts)}\nHEIGHT 1\n"
        f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(pts)}\nDATA {'binary' if binary else 'ascii'}\n"
    )
    body = (
        pts.tobytes()
        if binary
        else "".join(f"{x:.7g} {y:.7g} {z:.7g}\n" for x, y, z in pts).encode()
    )
    atomic_write(path, head.encode() + body)
    return path
