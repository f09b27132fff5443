"""PCD: LZF, ``binary_compressed`` (column-wise), point counts that must agree, z kept."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mfcl_jax.io import DataError, read_pcd
from mfcl_jax.io.lzf import LZFError, lzf_decompress


def lzf_compress(data: bytes) -> bytes:
    """A small greedy LZF encoder (hash of 3 bytes -> last position), for the tests only.

    It emits overlapping back-references (runs) and long ones (the extra length byte)."""
    out, lit, table = bytearray(), bytearray(), {}
    i, n = 0, len(data)

    def flush():
        while lit:
            chunk = lit[:32]
            out.append(len(chunk) - 1)
            out.extend(chunk)
            del lit[:32]

    while i < n:
        key = data[i : i + 3]
        ref = table.get(key) if len(key) == 3 else None
        if len(key) == 3:
            table[key] = i
        if ref is not None and i - ref <= 8192:
            length, most = 3, min(264, n - i)
            while length < most and data[ref + length] == data[i + length]:
                length += 1
            flush()
            dist, code = i - ref - 1, length - 2
            if code < 7:
                out.append((code << 5) | (dist >> 8))
            else:
                out += bytes([(7 << 5) | (dist >> 8), code - 7])
            out.append(dist & 0xFF)
            i += length
        else:
            lit.append(data[i])
            i += 1
    flush()
    return bytes(out)


def test_lzf_hand_made_back_references():
    # literal "abc", then a 3-byte copy from 3 back: "abcabc"
    assert lzf_decompress(bytes([2, 97, 98, 99, (1 << 5) | 0, 2]), 6) == b"abcabc"
    # literal "x", then a long overlapping copy (7 + 3 + 2 = 12 bytes from 1 back)
    assert lzf_decompress(bytes([0, 120, 7 << 5, 3, 0]), 13) == b"x" * 13
    # distance with the high bits in the control byte: 256 + 4 + 1 = 261 back
    head = bytes(range(256)) + b"WXYZ!"
    lit = (
        b"".join(bytes([31]) + head[k : k + 32] for k in range(0, 256, 32))
        + bytes([4])
        + head[256:]
    )
    data = lit + bytes([(2 << 5) | 1, 4])
    assert lzf_decompress(data, 265) == head + head[:4]


@pytest.mark.parametrize(
    "data, size, words",
    [
        (bytes([5, 1, 2]), 6, "literal run of 6 bytes"),
        (bytes([0, 1, (1 << 5), 9]), 4, "reaches 10 bytes back"),
        (bytes([0, 1, 7 << 5]), 12, "truncated"),
        (bytes([1, 1, 2]), 3, "decompressed to 2 bytes, header says 3"),
    ],
)
def test_lzf_corrupt(data, size, words):
    with pytest.raises(LZFError, match=words):
        lzf_decompress(data, size)


@given(st.lists(st.sampled_from([b"ab", b"abc", b"\x00" * 7, b"xyz", b"q"]), max_size=300))
def test_lzf_round_trip(parts):
    data = b"".join(parts) + bytes(range(40))
    packed = lzf_compress(data)
    assert lzf_decompress(packed, len(data)) == data


def _pcd_compressed(path, cols: dict, types: dict, points=None, width=None, size=None):
    """A PCL-style binary_compressed PCD: each field's column stored after the previous."""
    n = len(next(iter(cols.values())))
    names = list(cols)
    raw = b"".join(np.asarray(cols[f], types[f]).tobytes() for f in names)
    packed = lzf_compress(raw)
    head = (
        f"VERSION 0.7\nFIELDS {' '.join(names)}\n"
        f"SIZE {' '.join(str(np.dtype(types[f]).itemsize) for f in names)}\n"
        f"TYPE {' '.join(np.dtype(types[f]).kind.upper() for f in names)}\n"
        f"COUNT {' '.join('1' for _ in names)}\nWIDTH {width if width is not None else n}\n"
        f"HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points if points is not None else n}\n"
        "DATA binary_compressed\n"
    )
    body = struct.pack("<II", len(packed), len(raw) if size is None else size) + packed
    path.write_bytes(head.encode() + body)
    return path


def _autoware_cols(n=200, seed=0):
    rng = np.random.default_rng(seed)
    xyz = rng.normal(size=(n, 3)) * 10
    xyz[::7, 2] = 1.5  # repeated values give the encoder back-references
    cols = {
        "x": xyz[:, 0],
        "y": xyz[:, 1],
        "z": xyz[:, 2],
        "intensity": np.full(n, 7.0),
        "ring": np.arange(n) % 16,
    }
    types = {"x": "<f4", "y": "<f4", "z": "<f4", "intensity": "<f4", "ring": "<u2"}
    return xyz.astype(np.float32).astype(float), cols, types


def test_binary_compressed_reads_columns(tmp_path):
    xyz, cols, types = _autoware_cols()
    p = _pcd_compressed(tmp_path / "c.pcd", cols, types)
    np.testing.assert_array_equal(read_pcd(p), xyz[:, :2])
    pts, dropped = read_pcd(p, return_dropped=True, xyz=True)
    np.testing.assert_array_equal(pts, xyz)
    assert dropped == 0


def test_binary_compressed_nan_points_counted(tmp_path):
    xyz, cols, types = _autoware_cols(50)
    cols["x"][[3, 9]] = np.nan
    cols["z"][20] = np.inf
    p = _pcd_compressed(tmp_path / "n.pcd", cols, types)
    xy, dropped = read_pcd(p, return_dropped=True)
    assert dropped == 2 and len(xy) == 48
    pts, dropped = read_pcd(p, return_dropped=True, xyz=True)
    assert dropped == 3 and pts.shape == (47, 3)


def test_binary_compressed_errors(tmp_path):
    xyz, cols, types = _autoware_cols(30)
    p = _pcd_compressed(tmp_path / "s.pcd", cols, types, size=17)
    with pytest.raises(DataError) as e:
        read_pcd(p)
    assert "s.pcd" in str(e.value) and "30 points declared" in str(e.value)
    assert "expands to 17 bytes" in str(e.value)
    p = _pcd_compressed(tmp_path / "t.pcd", cols, types)
    p.write_bytes(p.read_bytes()[:-5])
    with pytest.raises(DataError, match=r"t\.pcd: binary_compressed header says \d+ compressed"):
        read_pcd(p)
    p = _pcd_compressed(tmp_path / "k.pcd", cols, types)
    raw = bytearray(p.read_bytes())
    start = raw.index(b"binary_compressed\n") + len(b"binary_compressed\n") + 8
    raw[start] = 31  # a literal run longer than the stream's start
    raw[start + 1 :] = raw[start + 1 : start + 10]
    raw[start - 8 : start - 4] = struct.pack("<I", len(raw) - start)
    p.write_bytes(bytes(raw))
    with pytest.raises(DataError, match=r"k\.pcd: corrupt binary_compressed data"):
        read_pcd(p)


def _ascii(path, n_decl, rows, width=None):
    w = n_decl if width is None else width
    head = (
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        f"WIDTH {w}\nHEIGHT 1\nPOINTS {n_decl}\nDATA ascii\n"
    )
    path.write_text(head + "".join(f"{i} {i + 1} {i + 2}\n" for i in range(rows)))
    return path


def test_point_counts_must_agree(tmp_path):
    with pytest.raises(DataError) as e:
        read_pcd(_ascii(tmp_path / "w.pcd", 3, 3, width=5))
    assert "w.pcd" in str(e.value) and "POINTS 3" in str(e.value) and "= 5" in str(e.value)
    # more data than declared: an error, no silent truncation
    with pytest.raises(DataError, match=r"m\.pcd: 2 points declared, ascii data holds 4"):
        read_pcd(_ascii(tmp_path / "m.pcd", 2, 4))
    p = tmp_path / "b.pcd"
    head = (
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n"
    )
    p.write_bytes(head.encode() + np.zeros((3, 3), "<f4").tobytes())
    before = p.read_bytes()
    with pytest.raises(DataError, match=r"b\.pcd: 2 points declared, binary data holds 3"):
        read_pcd(p)
    assert p.read_bytes() == before  # the input is left as it was


def test_xyz_needs_z(tmp_path):
    p = tmp_path / "xy.pcd"
    p.write_text(
        "VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\n"
        "POINTS 1\nDATA ascii\n1 2\n"
    )
    np.testing.assert_array_equal(read_pcd(p), [[1, 2]])
    with pytest.raises(DataError, match=r"xy\.pcd: missing field 'z' \(fields are \['x', 'y'\]\)"):
        read_pcd(p, xyz=True)


def test_ascii_and_binary_keep_z(tmp_path):
    from mfcl_jax.io import write_pcd

    pts = np.random.default_rng(3).normal(size=(20, 3))
    for binary in (True, False):
        back = read_pcd(write_pcd(tmp_path / f"{binary}.pcd", pts, binary=binary), xyz=True)
        np.testing.assert_allclose(back, pts, atol=1e-5)
