"""LZF decompression (the format of liblzf, used by PCL's ``DATA binary_compressed``).

A compressed stream is a sequence of chunks, each led by a control byte ``c``:

- ``c < 32``: a literal run; the next ``c + 1`` bytes are copied to the output;
- ``c >= 32``: a back-reference of length ``(c >> 5) + 2`` (when ``c >> 5 == 7`` the next
  byte is added to the length), then one more byte ``lo``; the copy starts
  ``((c & 31) << 8) + lo + 1`` bytes before the end of the output so far. The source may
  overlap the bytes being written (a run that repeats its own start).

Pure Python on ``bytearray`` slices: one step per chunk, not per byte, so a scan of a few
hundred thousand points decodes in well under a second. No PyPI package for LZF is kept
up to date, hence this small decoder.
"""

from __future__ import annotations

__all__ = ["lzf_decompress", "LZFError"]


class LZFError(ValueError):
    """A corrupt LZF stream (the message says where it breaks)."""


def lzf_decompress(data: bytes, size: int) -> bytes:
    """Decompresses an LZF stream that must expand to exactly ``size`` bytes.

    Args:
        data: the compressed bytes.
        size: the expected decompressed size.

    Returns:
        the ``size`` decompressed bytes.

    Raises:
        LZFError: a truncated stream, a back-reference before the start of the output, or an
            output whose length differs from ``size``.
    """
    src = memoryview(bytes(data))
    n = len(src)
    out = bytearray()
    i = 0
    while i < n:
        c = src[i]
        i += 1
        if c < 32:
            run = c + 1
            if i + run > n:
                raise LZFError(f"literal run of {run} bytes at input byte {i - 1} is truncated")
            out += src[i : i + run]
            i += run
            continue
        length = c >> 5
        if length == 7:
            if i >= n:
                raise LZFError(f"back-reference at input byte {i - 1} is truncated")
            length += src[i]
            i += 1
        if i >= n:
            raise LZFError(f"back-reference at input byte {i - 1} is truncated")
        dist = ((c & 31) << 8) + src[i] + 1
        i += 1
        length += 2
        start = len(out) - dist
        if start < 0:
            raise LZFError(
                f"back-reference at input byte {i - 2} reaches {dist} bytes back, "
                f"but only {len(out)} bytes are decoded"
            )
        if dist >= length:
            out += out[start : start + length]
        else:  # overlapping copy: the last `dist` bytes repeat
            pattern = out[start:]
            reps = -(-length // dist)
            out += (pattern * reps)[:length]
        if len(out) > size:
            break
    if len(out) != size:
        raise LZFError(f"decompressed to {len(out)} bytes, header says {size}")
    return bytes(out)
