"""Exact symmetric copies: a ``Plan`` seen through a mirror and quarter turns about the origin."""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import Polygon, box

from mfcl_jax.sim.families.common import Plan

__all__ = ["View"]


class View:
    """A ``Plan`` seen through an exact map: a mirror ``x -> -x`` then ``rot`` quarter turns.

    Symmetric families describe one unit in local coordinates and replay it through views;
    both maps only swap and negate coordinates, so the copies are exact in floating point.
    """

    def __init__(self, plan: Plan, rot: int = 0, mirror: bool = False):
        self.plan, self.rot, self.mirror = plan, rot % 4, mirror

    def map(self, p) -> np.ndarray:
        """Maps points ``(..., 2)``."""
        p = np.asarray(p, float)
        x, y = (-p[..., 0] if self.mirror else p[..., 0]), p[..., 1]
        for _ in range(self.rot):
            x, y = -y, x
        return np.stack([x, y], axis=-1)

    def wall(self, p0, p1, t: float | None = None) -> None:
        self.plan.wall(self.map(p0), self.map(p1), t)

    def box(self, x0, y0, x1, y1, t: float | None = None) -> None:
        c = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        for i in range(4):
            self.wall(c[i], c[(i + 1) % 4], t)

    def polygon(self, cell) -> Polygon:
        cell = cell if isinstance(cell, Polygon) else box(*cell)
        return shapely.transform(cell, self.map).normalize()

    def room(self, name: str, cell) -> None:
        self.plan.room(name, self.polygon(cell))

    def door(self, centre, normal, width: float, rooms) -> int:
        return self.plan.door(self.map(centre), self.map(normal), width, rooms)

    def gap(self, p, q) -> None:
        self.plan.gap(self.map(p), self.map(q))

    def solid(self, poly) -> None:
        self.plan.solid(self.polygon(poly))
