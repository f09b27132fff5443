"""Reading a ROS map_server map into occupied / free cell masks.

Cells are classified the map_server way: ``p = (255 - v) / 255`` (or ``v / 255`` when
``negate``), occupied if ``p > occupied_thresh``, free if ``p < free_thresh``, unknown
otherwise.

A common trap: maps saved by some tools write unknown space as grey 205 or 206, and
``(255 - 206) / 255 = 0.192`` falls just under the usual ``free_thresh: 0.196``, so the
unknown space around and between the rooms reads as free (willow-full is such a map). When
the most common grey level that is read as free but lies within ``GREY_MARGIN`` under
``free_thresh`` covers at least ``GREY_SHARE`` of the image, a ``FloorplanWarning`` gives
the level, its share, its ``p`` and the ``--free-thresh`` value that would read it as
unknown. Nothing is changed silently: the thresholds stay the file's unless overridden
explicitly (``load_rosmap(free_thresh=...)``, ``mfcl ... --free-thresh``).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import yaml

from mfcl_jax.floorplan.model import FloorplanError, FloorplanWarning

__all__ = ["read_rosmap_grid", "unknown_grey_read_as_free", "GREY_SHARE", "GREY_MARGIN"]

GREY_SHARE = 0.05
GREY_MARGIN = 0.05

_REQUIRED = ("image", "resolution", "origin")


def _field(path, data, name, default=None, kind=float):
    if name not in data:
        if default is None:
            raise FloorplanError(f"{path}: missing field {name!r}")
        return default
    value = data[name]
    try:
        out = kind(value)
    except (TypeError, ValueError):
        raise FloorplanError(f"{path}: bad field {name}={value!r}") from None
    return out


def read_rosmap_grid(yaml_path, free_thresh: float | None = None, occupied_thresh=None):
    """Reads a map_server map.

    Returns:
        ``(occ (H, W) bool, free (H, W) bool, res, origin (x, y, yaw))`` with row 0 at the
        bottom of the map (world y grows with the row index).
    """
    from PIL import Image

    path = Path(yaml_path)
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise FloorplanError(f"{path}: file not found") from None
    except yaml.YAMLError as e:
        raise FloorplanError(f"{path}: not valid YAML ({e})") from None
    if not isinstance(data, dict):
        raise FloorplanError(f"{path}: expected a mapping with fields {', '.join(_REQUIRED)}")
    image = data.get("image")
    if not isinstance(image, str) or not image:
        raise FloorplanError(f"{path}: bad field image={image!r}")
    res = _field(path, data, "resolution")
    if not (math.isfinite(res) and res > 0):
        raise FloorplanError(f"{path}: bad field resolution={data['resolution']!r} (need > 0)")
    origin = data.get("origin")
    try:
        origin = [float(v) for v in origin]
        assert len(origin) == 3 and all(math.isfinite(v) for v in origin)
    except (TypeError, ValueError, AssertionError):
        raise FloorplanError(f"{path}: bad field origin={origin!r} (need [x, y, yaw])") from None
    negate = _field(path, data, "negate", 0, int)
    if negate not in (0, 1):
        raise FloorplanError(f"{path}: bad field negate={data['negate']!r} (need 0 or 1)")
    occ_t = _field(path, data, "occupied_thresh", 0.65)
    free_t = _field(path, data, "free_thresh", 0.196)
    occ_t = occ_t if occupied_thresh is None else float(occupied_thresh)
    free_t = free_t if free_thresh is None else float(free_thresh)
    if not 0.0 <= free_t < occ_t <= 1.0:
        raise FloorplanError(
            f"{path}: bad fields free_thresh={free_t!r}, occupied_thresh={occ_t!r} "
            "(need 0 <= free_thresh < occupied_thresh <= 1)"
        )
    img_path = (path.parent / image) if not Path(image).is_absolute() else Path(image)
    try:
        img = Image.open(img_path)
        img.load()
    except FileNotFoundError:
        raise FloorplanError(f"{path}: image file {str(img_path)!r} not found") from None
    except Exception as e:
        raise FloorplanError(f"{path}: cannot read image {str(img_path)!r} ({e})") from None
    v = np.asarray(img.convert("L"), dtype=np.float64)
    p = v / 255.0 if negate else (255.0 - v) / 255.0
    grey = unknown_grey_read_as_free(v, free_t, bool(negate))
    if grey is not None:
        level, share, p_level, suggest = grey
        warnings.warn(
            f"{path}: {100 * share:.1f} % of the pixels have grey level {level} "
            f"(p = {p_level:.4f}), just under free_thresh={free_t:g}, so they are read as "
            f"free space; if that grey marks unknown space, pass --free-thresh {suggest:g} "
            "(or set free_thresh in the YAML)",
            FloorplanWarning,
            stacklevel=2,
        )
    occ = np.flipud(p > occ_t)
    free = np.flipud(p < free_t)
    return occ, free, float(res), tuple(origin)


def unknown_grey_read_as_free(v: np.ndarray, free_t: float, negate: bool = False):
    """The module's unknown-grey check on grey values ``v (H, W)``.

    Returns:
        ``None``, or ``(level, share, p, suggested_free_thresh)`` for a grey level that is
        common, read as free, and close under ``free_t``.
    """
    levels, counts = np.unique(np.asarray(v, np.uint8), return_counts=True)
    p_all = levels / 255.0 if negate else (255.0 - levels) / 255.0
    near = (p_all >= free_t - GREY_MARGIN) & (p_all < free_t)
    if not near.any():
        return None
    j = int(np.argmax(np.where(near, counts, 0)))
    level, share, p = int(levels[j]), counts[j] / v.size, float(p_all[j])
    if share < GREY_SHARE:
        return None
    suggest = math.floor(p * 100) / 100
    if suggest >= p:
        suggest -= 0.01
    return level, float(share), p, suggest
