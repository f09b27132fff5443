"""From a built plan and its walks to a checked ``Scene`` with default furniture."""

from __future__ import annotations

import numpy as np

from mfcl_jax.sim.families.clutter import furnish
from mfcl_jax.sim.families.common import Built, draw
from mfcl_jax.sim.families.walks import CLEAR, clearance, polyline_length
from mfcl_jax.sim.scenes import Scene
from mfcl_jax.sim.trajectory import sample_path

__all__ = ["finish", "WALK_LENGTH"]

# Every walk is this long (m): long enough for several 6 m windows, short enough to simulate.
WALK_LENGTH = (30.0, 80.0)
# Default furniture covers this fraction of the floor (moderate).
_DEFAULT_CLUTTER = (0.04, 0.09)


def finish(built: Built, walks: dict, rng: np.random.Generator, description: str) -> Scene:
    """Checks the walks against the plan, furnishes the rooms and returns the scene.

    Raises:
        ValueError: a walk shorter or longer than ``WALK_LENGTH`` or closer than ``CLEAR``
            to a wall (generator bugs, reported with the scene and walk names).
    """
    fp = built.fp
    lo, hi = WALK_LENGTH
    for name, wp in walks.items():
        # The driven (smoothed) path is a little shorter than the polyline.
        n0, n1 = sample_path(wp).s[-1], polyline_length(wp)
        if not (n0 >= lo and n1 <= hi):
            raise ValueError(
                f"{fp.name}: walk {name!r} is {n0:.1f}-{n1:.1f} m long, not in [{lo}, {hi}]"
            )
        c = clearance(wp, fp.wall_faces)
        if c < CLEAR + 0.05:
            raise ValueError(f"{fp.name}: walk {name!r} passes {c:.2f} m from a wall")
    fraction = draw(rng, *_DEFAULT_CLUTTER, step=0.005)
    clutter, _ = furnish(fp, walks.values(), fraction, rng)
    return Scene(fp.name, fp, clutter, walks, description=description)
