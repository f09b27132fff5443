"""Held-out maps: an occupancy map of a log built from a chosen subset of its scans, cached.

A benchmark window is localized against a map of the same building built WITHOUT the window's
own scans, the stand-in for a prior map. Building one takes seconds (ray counting, then the
room segmentation of ``load_rosmap``), so the written ROS map (YAML + PGM) is kept in a cache
folder together with a JSON record of the scans it was built from. The cache key covers
everything the map's pixels depend on: the log's content (a hash of the file), the scans used,
the resolution, the occupancy parameters and ``MAP_VERSION``. A warm call reads the PGM back and
re-runs only ``load_rosmap`` (its segmentation may change between versions of the package; the
map's pixels do not).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.io.atomic import atomic_write_text
from mfcl_jax.sources.occmap import occupancy_grid, write_rosmap

__all__ = [
    "MAP_VERSION",
    "HeldOutMap",
    "default_cache_dir",
    "file_digest",
    "held_out_map",
    "recorded_scans",
]

# Bump whenever occupancy_grid or write_rosmap change the pixels they write.
MAP_VERSION = "occ1"


@dataclass(frozen=True, eq=False)
class HeldOutMap:
    """A map built from some of a log's scans.

    Attributes:
        floorplan: the map loaded by ``load_rosmap``.
        yaml_path: the cached map's YAML file.
        scans: ``(M,)`` indices (into the log's scans) of the scans the map was built from,
            as recorded next to the map when it was written.
        cached: True when the map came from the cache.
        seconds: time spent (build + write + load, or load only).
        free: ``(H, W)`` the map's free cells, row 0 at the bottom.
        res: cell size (m).
        origin: ``(x, y)`` of the lower-left cell corner.
    """

    floorplan: Floorplan
    yaml_path: Path
    scans: np.ndarray
    cached: bool
    seconds: float
    free: np.ndarray
    res: float
    origin: tuple[float, float]

    def coverage(self, xy) -> float:
        """Fraction of the points ``xy (K, 2)`` that lie on free cells of the map."""
        ij = np.floor((np.asarray(xy, np.float64) - self.origin) / self.res).astype(np.int64)
        h, w = self.free.shape
        inside = (ij[:, 0] >= 0) & (ij[:, 0] < w) & (ij[:, 1] >= 0) & (ij[:, 1] < h)
        on = np.zeros(len(ij), bool)
        on[inside] = self.free[ij[inside, 1], ij[inside, 0]]
        return float(on.mean()) if len(on) else 0.0


def default_cache_dir() -> Path:
    """``$MFCL_CACHE/maps``, else ``$XDG_CACHE_HOME/mfcl_jax/maps``, else
    ``~/.cache/mfcl_jax/maps``."""
    if os.environ.get("MFCL_CACHE"):
        return Path(os.environ["MFCL_CACHE"]) / "maps"
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "mfcl_jax" / "maps"


def file_digest(path) -> str:
    """SHA-1 of a file's bytes (the data part of the cache key)."""
    h = hashlib.sha1()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def held_out_map(
    poses,
    scans,
    use,
    res: float,
    data_id: str,
    stem: str,
    cache_dir=None,
    **occupancy,
) -> HeldOutMap:
    """The occupancy map of ``scans[use]`` seen from ``poses[use]``, from the cache if there.

    Args:
        poses: ``(N, 3)`` sensor poses of the whole log (map frame).
        scans: ``N`` arrays ``(n_i, 2)``, sensor-frame points.
        use: ``(M,)`` indices of the scans to build the map from.
        res: cell size (m).
        data_id: identifies the log's content (name and ``file_digest``).
        stem: readable prefix of the cached file names (e.g. ``"intel_w03"``).
        cache_dir: cache folder (default ``default_cache_dir()``).
        **occupancy: overrides of ``occupancy_grid``'s parameters (part of the key).

    Returns:
        A ``HeldOutMap``.
    """
    from mfcl_jax.floorplan.rosmap import load_rosmap, read_rosmap_grid

    t0 = time.perf_counter()
    use = np.unique(np.asarray(use, np.int64))
    key = json.dumps(
        dict(
            version=MAP_VERSION,
            data=data_id,
            res=round(float(res), 6),
            occupancy=sorted(occupancy.items()),
            scans=hashlib.sha1(use.tobytes()).hexdigest(),
        ),
        sort_keys=True,
    )
    digest = hashlib.sha1(key.encode()).hexdigest()[:12]
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    yaml_path = folder / f"{stem}_r{round(res * 1000)}mm_{digest}.yaml"
    record = yaml_path.with_suffix(".json")
    cached = record.is_file() and yaml_path.is_file() and yaml_path.with_suffix(".pgm").is_file()
    if not cached:
        occ, free, origin = occupancy_grid(
            np.asarray(poses)[use], [scans[i] for i in use], res=res, **occupancy
        )
        write_rosmap(yaml_path, occ, free, res, origin)
        # Written last: its presence marks a complete cache entry.
        atomic_write_text(record, json.dumps(dict(key=json.loads(key), scans=use.tolist())))
    fp = load_rosmap(yaml_path)
    _, free, res_read, (ox, oy, _) = read_rosmap_grid(yaml_path)
    return HeldOutMap(
        fp,
        yaml_path,
        recorded_scans(yaml_path),
        cached,
        time.perf_counter() - t0,
        free,
        res_read,
        (ox, oy),
    )


def recorded_scans(yaml_path) -> np.ndarray:
    """``(M,)`` the scan indices a cached map was built from (its JSON record)."""
    record = Path(yaml_path).with_suffix(".json")
    return np.asarray(json.loads(record.read_text())["scans"], np.int64)
