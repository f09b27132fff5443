"""A building to simulate in (``Scene``), and ``rect_segments`` to draw its clutter.

A ``Scene`` is what the simulator needs to play a robot through a building: the as-designed
floor plan (what the localizer is given), the clutter that the LiDAR sees but the floor plan
does not contain (furniture, later partitions), and named trajectories as waypoints in B.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mfcl_jax.floorplan.model import Floorplan
from mfcl_jax.sim.world3d import DEFAULT_CLUTTER_HEIGHT

__all__ = ["Scene", "rect_segments"]


@dataclass(frozen=True, eq=False)
class Scene:
    """A building to simulate in.

    Attributes:
        name: registry name.
        floorplan: the as-designed model (the only geometry a localizer may use).
        clutter: ``(K, 2, 2)`` segments the LiDAR sees that are not in ``floorplan``.
        trajectories: name -> ``(P, 2)`` waypoints in B (polyline; corners are smoothed by
            the trajectory sampler).
        description: a few lines on what the scene is for.
        clutter_height: ``(K,)`` height (m) of each clutter segment above the floor, for the
            3-D LiDAR (``inf``: up to the ceiling); ``None`` gives every segment
            ``DEFAULT_CLUTTER_HEIGHT``. The 2-D simulator ignores it.
        as_built: ``(F, 2, 2)`` wall-face segments the LiDAR actually sees, where reality
            deviates from the plan (a missing wall, a moved door, a plan drawn at the wrong
            scale); ``None`` when the walls are as designed (``floorplan.wall_faces``).
    """

    name: str
    floorplan: Floorplan
    clutter: np.ndarray
    trajectories: dict[str, np.ndarray] = field(default_factory=dict)
    description: str = ""
    clutter_height: np.ndarray | None = None
    as_built: np.ndarray | None = None

    def __post_init__(self):
        clutter = np.asarray(self.clutter, dtype=np.float64).reshape(-1, 2, 2)
        object.__setattr__(self, "clutter", clutter)
        h = self.clutter_height
        h = np.full(len(clutter), DEFAULT_CLUTTER_HEIGHT) if h is None else np.asarray(h, float)
        if h.shape != (len(clutter),) or not np.all(h > 0):
            raise ValueError(
                f"scene {self.name!r}: clutter_height needs {len(clutter)} heights > 0, got "
                f"shape {h.shape} (min {np.min(h, initial=np.inf)})"
            )
        object.__setattr__(self, "clutter_height", h)
        if self.as_built is not None:
            faces = np.asarray(self.as_built, dtype=np.float64).reshape(-1, 2, 2)
            object.__setattr__(self, "as_built", faces)
        trajs = {k: np.asarray(v, dtype=np.float64) for k, v in self.trajectories.items()}
        for k, v in trajs.items():
            if v.ndim != 2 or v.shape[1] != 2 or len(v) < 2:
                raise ValueError(
                    f"scene {self.name!r}: trajectory {k!r} needs (P>=2, 2) "
                    f"waypoints, got shape {v.shape}"
                )
        object.__setattr__(self, "trajectories", trajs)

    @property
    def segments(self) -> np.ndarray:
        """Everything the LiDAR can hit: real wall faces then clutter, ``(F + K, 2, 2)``."""
        walls = self.floorplan.wall_faces if self.as_built is None else self.as_built
        return np.concatenate([walls, self.clutter], axis=0)


def rect_segments(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """The four sides of an axis-aligned rectangle as segments ``(4, 2, 2)``."""
    c = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)
    return np.stack([c, np.roll(c, -1, axis=0)], axis=1)
