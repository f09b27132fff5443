"""Occupancy maps from a log (poses + scans), written as ROS map_server maps.

Counting model: every beam end point is a hit in its cell; cells the beam crosses before it
(sampled every ``res / 2``, stopping ``2 res`` short of the hit) are passes. A cell is
occupied when ``hits >= min_hits`` and ``hits / (hits + passes) >= occ_ratio``, free when it
was passed and is not occupied, unknown otherwise. The map is written as a PGM (occupied 0,
free 254, unknown 205) and a YAML that ``floorplan.load_rosmap`` reads back, so the
localizer's room segmentation, doors and gate come from the map alone.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from mfcl_jax.io.atomic import atomic_write_text

__all__ = ["occupancy_grid", "write_rosmap"]


def occupancy_grid(
    poses,
    scans,
    res: float = 0.10,
    max_range: float = 15.0,
    min_hits: int = 2,
    occ_ratio: float = 0.25,
    margin: float = 1.0,
):
    """Occupied / free grids from sensor poses in the map frame and sensor-frame scans.

    Args:
        poses: ``(N, 3)`` sensor poses.
        scans: ``N`` arrays ``(n_i, 2)``.
        res: cell size (m).
        max_range: beams longer than this are ignored (m).
        min_hits, occ_ratio: occupancy rule (module doc).
        margin: border around the data (m).

    Returns:
        ``(occ (H, W) bool, free (H, W) bool, origin (x0, y0))`` with row 0 at the bottom.
    """
    poses = np.asarray(poses, np.float64)
    ends, starts = [], []
    for p, s in zip(poses, scans, strict=True):
        s = np.asarray(s, np.float64).reshape(-1, 2)
        s = s[np.hypot(s[:, 0], s[:, 1]) <= max_range]
        c, si = np.cos(p[2]), np.sin(p[2])
        w = np.stack([p[0] + c * s[:, 0] - si * s[:, 1], p[1] + si * s[:, 0] + c * s[:, 1]], -1)
        ends.append(w)
        starts.append(np.broadcast_to(p[:2], w.shape))
    ends = np.concatenate(ends)
    starts = np.concatenate(starts)
    lo = np.minimum(ends.min(0), poses[:, :2].min(0)) - margin
    hi = np.maximum(ends.max(0), poses[:, :2].max(0)) + margin
    W, H = np.ceil((hi - lo) / res).astype(int) + 1
    hits = np.zeros(H * W, np.int64)
    passes = np.zeros(H * W, np.int64)

    def cells(xy):
        ij = np.floor((xy - lo) / res).astype(np.int64)
        return ij[:, 1] * W + ij[:, 0]

    np.add.at(hits, cells(ends), 1)
    d = ends - starts
    length = np.hypot(d[:, 0], d[:, 1])
    step = res / 2
    n = np.maximum(np.floor((length - 2 * res) / step).astype(int), 0)
    # Ray samples in chunks to bound memory.
    chunk = 200_000
    for a in range(0, len(ends), chunk):
        nn = n[a : a + chunk]
        rep = np.repeat(np.arange(a, a + len(nn)), nn)
        k = np.arange(len(rep)) - np.repeat(np.cumsum(nn) - nn, nn)
        f = (k * step / np.maximum(length[rep], 1e-9))[:, None]
        xy = starts[rep] + f * d[rep]
        passes += np.bincount(cells(xy), minlength=H * W)
    occ = (hits >= min_hits) & (hits >= occ_ratio * (hits + passes))
    free = (passes > 0) & ~occ
    return occ.reshape(H, W), free.reshape(H, W), (float(lo[0]), float(lo[1]))


def write_rosmap(yaml_path, occ, free, res: float, origin) -> Path:
    """Writes ``occ``/``free`` (row 0 at the bottom) as a map_server YAML + PGM pair."""
    from PIL import Image

    yaml_path = Path(yaml_path)
    yaml_path.parent.mkdir(parents=True, exist_ok=True)
    img = np.full(occ.shape, 205, np.uint8)
    img[free] = 254
    img[occ] = 0
    pgm = yaml_path.with_suffix(".pgm")
    tmp = pgm.with_name(f".{pgm.name}.tmp")
    Image.fromarray(np.flipud(img)).save(tmp, format="PPM")
    tmp.replace(pgm)
    meta = dict(
        image=pgm.name,
        resolution=float(res),
        origin=[float(origin[0]), float(origin[1]), 0.0],
        negate=0,
        occupied_thresh=0.65,
        free_thresh=0.196,
    )
    atomic_write_text(yaml_path, yaml.safe_dump(meta, sort_keys=False))
    return yaml_path
