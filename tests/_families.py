"""Shared by the procedural building families' tests: every family's scenes of the first
seeds, built once per worker, and the geometry checks on walks and regions."""

from __future__ import annotations

from functools import cache

import numpy as np
import shapely
from shapely.geometry import MultiLineString

from mfcl_jax.sim.families import FAMILIES, make_scene
from mfcl_jax.sim.families.walks import dense
from mfcl_jax.sim.trajectory import sample_path

SEEDS = range(5)


@cache
def all_scenes():
    """``make_scene`` of every family and seed of ``SEEDS`` (read-only: tests share them)."""
    return {(f, s): make_scene(f, s) for f in FAMILIES for s in SEEDS}


def _driven(wp):
    """Points along the waypoint polyline and along the smoothed path the simulator drives."""
    return np.concatenate([dense(wp), sample_path(wp).poses[:, :2]])


def _min_dist(points, segments) -> float:
    lines = MultiLineString([s for s in np.asarray(segments)])
    return float(np.min(shapely.distance(lines, shapely.points(points))))


def _same_region(a, b, tol=1e-6) -> bool:
    return a.symmetric_difference(b).area < tol


def _centre(fp):
    x0, y0, x1, y1 = fp.bounds
    return ((x0 + x1) / 2, (y0 + y1) / 2)
