"""PCD point clouds (``DATA ascii``, ``binary`` and ``binary_compressed``).

``read_pcd`` returns planar points ``(n, 2)`` (x, y) or, with ``xyz=True``, ``(n, 3)``; other
fields (``intensity``, ``ring``, ...) are read past. Points with a non-finite kept coordinate
are dropped and counted, never silently repaired (a NaN z does not drop a planar point).

``binary_compressed`` is PCL's and Autoware's default: after the ``DATA`` line come two
little-endian uint32 (compressed size, decompressed size) and an LZF stream
(``mfcl_jax.io.lzf``) that expands to the fields stored one after the other, each field's
values for all points together (column-wise).

The point count must agree everywhere: ``POINTS`` with ``WIDTH * HEIGHT``, and both with the
data present (a file with more or fewer points than declared is an error naming both counts).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from mfcl_jax.io.atomic import atomic_write
from mfcl_jax.io.errors import DataError

__all__ = ["read_pcd", "write_pcd", "pcd_fields"]

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


def _header(path: Path, raw: bytes) -> tuple[dict, int]:
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
            return header, pos


def _count(path: Path, header: dict) -> int:
    def num(key, default):
        vals = header.get(key, [default])
        try:
            v = int(vals[0])
        except (ValueError, IndexError):
            shown = " ".join(vals)
            raise DataError(f"{path}: header field {key}={shown!r} is not a count") from None
        if v < 0:
            raise DataError(f"{path}: header field {key}={v} is negative")
        return v

    w, h = num("WIDTH", "0"), num("HEIGHT", "1")
    if "POINTS" not in header:
        return w * h
    n = num("POINTS", "0")
    if "WIDTH" in header and n != w * h:
        raise DataError(f"{path}: header POINTS {n} disagrees with WIDTH*HEIGHT {w}*{h} = {w * h}")
    return n


def pcd_fields(path) -> list[str]:
    """The ``FIELDS`` of a PCD file, from its header alone (e.g. does it hold ``z``?).

    Raises:
        DataError: missing or unreadable file, a header without a DATA line.
    """
    path = Path(path)
    try:
        with path.open("rb") as f:
            raw = f.read(1 << 16)
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    except OSError as e:
        raise DataError(f"{path}: cannot read ({e.strerror})") from None
    return list(_header(path, raw)[0].get("FIELDS", []))


def read_pcd(path, return_dropped: bool = False, xyz: bool = False):
    """Reads the coordinates of a PCD file.

    Args:
        path: a ``.pcd`` file, ``DATA ascii``, ``binary`` or ``binary_compressed``.
        return_dropped: also return how many points had a non-finite kept coordinate.
        xyz: keep z as well: return ``(n, 3)`` points (the file then needs a field ``z``).

    Returns:
        ``points (n, 2)`` (or ``(n, 3)``) float64, or ``(points, n_dropped)``.

    Raises:
        DataError: missing file, a header without the fields needed (the fields present are
            listed), an unsupported field type or data format, a point count that disagrees
            between ``POINTS``, ``WIDTH * HEIGHT`` and the data, or corrupt compressed data.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    except OSError as e:
        raise DataError(f"{path}: cannot read ({e.strerror})") from None
    header, pos = _header(path, raw)
    fields = header.get("FIELDS", [])
    want = ("x", "y", "z") if xyz else ("x", "y")
    for f in want:
        if f not in fields:
            raise DataError(f"{path}: missing field {f!r} (fields are {fields})")
    n_f = len(fields)
    try:
        sizes = [int(v) for v in header.get("SIZE", ["4"] * n_f)]
        counts = [int(v) for v in header.get("COUNT", ["1"] * n_f)]
    except ValueError:
        raise DataError(f"{path}: SIZE or COUNT holds a non-integer") from None
    types = header.get("TYPE", ["F"] * n_f)
    if not len(sizes) == len(types) == len(counts) == n_f:
        raise DataError(f"{path}: FIELDS, SIZE, TYPE and COUNT lengths differ")
    for f, t, s in zip(fields, types, sizes, strict=True):
        if (t.upper(), s) not in _TYPES:
            raise DataError(f"{path}: field {f!r} has unsupported TYPE {t} SIZE {s}")
    dtypes = [np.dtype("<" + _TYPES[(t.upper(), s)]) for t, s in zip(types, sizes, strict=True)]
    n = _count(path, header)
    fmt = header["DATA"][0].lower() if header["DATA"] else ""
    idx = [fields.index(f) for f in want]
    body = raw[pos:]
    if fmt == "ascii":
        cols = _ascii(path, body, n, counts, idx)
    elif fmt == "binary":
        cols = _binary(path, body, n, fields, dtypes, counts, idx)
    elif fmt == "binary_compressed":
        cols = _compressed(path, body, n, dtypes, counts, idx)
    else:
        raise DataError(f"{path}: unsupported DATA {fmt!r} (ascii, binary or binary_compressed)")
    pts = np.stack(cols, -1).reshape(-1, len(want))
    ok = np.all(np.isfinite(pts), axis=1)
    dropped = int(np.count_nonzero(~ok))
    pts = np.ascontiguousarray(pts[ok])
    return (pts, dropped) if return_dropped else pts


def _ascii(path, body, n, counts, idx) -> list[np.ndarray]:
    text = body.decode("ascii", "replace").split()
    width = sum(counts)
    if len(text) != n * width:
        extra = f" and {len(text) % width} extra values" if len(text) % width else ""
        raise DataError(
            f"{path}: {n} points declared, ascii data holds {len(text) // width}{extra}"
        )
    vals = np.asarray(text, dtype=object).reshape(n, width)
    col = np.cumsum([0] + counts)
    try:
        return [vals[:, col[i]].astype(float) for i in idx]
    except ValueError as e:
        raise DataError(f"{path}: non-numeric ascii data ({e})") from None


def _binary(path, body, n, fields, dtypes, counts, idx) -> list[np.ndarray]:
    dt = np.dtype(
        [
            (f"{f}_{i}", d, (c,) if c > 1 else ())
            for i, (f, d, c) in enumerate(zip(fields, dtypes, counts, strict=True))
        ]
    )
    if len(body) < n * dt.itemsize:
        raise DataError(
            f"{path}: binary data truncated ({n} points declared, data holds "
            f"{len(body) // dt.itemsize})"
        )
    if len(body) > n * dt.itemsize:
        rest = len(body) % dt.itemsize
        extra = f" and {rest} extra bytes" if rest else ""
        raise DataError(
            f"{path}: {n} points declared, binary data holds {len(body) // dt.itemsize}{extra}"
        )
    rec = np.frombuffer(body, dtype=dt, count=n)
    return [rec[dt.names[i]].reshape(n, -1)[:, 0].astype(float) if n else np.zeros(0)
            for i in idx]  # fmt: skip


def _compressed(path, body, n, dtypes, counts, idx) -> list[np.ndarray]:
    from mfcl_jax.io.lzf import LZFError, lzf_decompress

    if len(body) < 8:
        raise DataError(f"{path}: binary_compressed data has no size words")
    packed, size = struct.unpack("<II", body[:8])
    data = body[8:]
    if len(data) != packed:
        raise DataError(
            f"{path}: binary_compressed header says {packed} compressed bytes, "
            f"the file holds {len(data)}"
        )
    point = sum(d.itemsize * c for d, c in zip(dtypes, counts, strict=True))
    if size != n * point:
        held = f"{size / point:g}" if point else "?"
        raise DataError(
            f"{path}: {n} points declared ({n * point} bytes), binary_compressed data "
            f"expands to {size} bytes ({held} points)"
        )
    try:
        buf = lzf_decompress(data, size)
    except LZFError as e:
        raise DataError(f"{path}: corrupt binary_compressed data ({e})") from None
    starts = np.cumsum([0] + [n * d.itemsize * c for d, c in zip(dtypes, counts, strict=True)])
    out = []
    for i in idx:
        col = np.frombuffer(buf, dtypes[i], count=n * counts[i], offset=int(starts[i]))
        out.append(col.reshape(n, counts[i])[:, 0].astype(float))
    return out


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
    pts = pts.astype("<f4")
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
