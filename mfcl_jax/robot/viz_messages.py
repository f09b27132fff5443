"""Fields of Foxglove's well-known messages (``robot.viz``, ``robot.viz_live``): times, planar
poses, line lists and the outlines they draw."""

from __future__ import annotations

import math

import numpy as np
import shapely

__all__ = ["LINE_LIST", "stamp_of", "pose_msg", "poses", "line_list", "ring_segments"]

LINE_LIST = 2  # foxglove.LinePrimitive type


def stamp_of(ns: int) -> dict:
    """A Foxglove ``Time`` of nanoseconds."""
    sec, nsec = divmod(ns, 10**9)
    return {"sec": sec, "nsec": nsec}


def pose_msg(x: float, y: float, yaw: float = 0.0) -> dict:
    """A Foxglove ``Pose`` in the plane."""
    return {
        "position": {"x": float(x), "y": float(y), "z": 0.0},
        "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
    }


def poses(rows) -> list[dict]:
    """``pose_msg`` of every ``(x, y, yaw)`` row."""
    return [pose_msg(x, y, yaw) for x, y, yaw in rows]


def line_list(segments, rgba, thickness: float) -> dict:
    """One LINE_LIST primitive of ``segments (n, 2, 2)`` (scale-invariant: pixels)."""
    pts = [{"x": float(x), "y": float(y), "z": 0.0} for x, y in np.reshape(segments, (-1, 2))]
    return {
        "type": LINE_LIST,
        "pose": pose_msg(0.0, 0.0),
        "thickness": thickness,
        "scale_invariant": True,
        "points": pts,
        "color": dict(zip("rgba", rgba, strict=True)),
        "colors": [],
        "indices": [],
    }


def ring_segments(geoms) -> np.ndarray:
    """The outline segments ``(n, 2, 2)`` of (multi)polygons, holes included."""
    segs = [np.zeros((0, 2, 2))]
    for p in shapely.get_parts(list(geoms)):
        for ring in [p.exterior, *p.interiors]:
            c = np.asarray(ring.coords, np.float64)[:, :2]
            segs.append(np.stack([c[:-1], c[1:]], 1))
    return np.concatenate(segs)
