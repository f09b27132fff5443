"""Built-in stand-in buildings for simulation, by name.

A ``Scene`` (``sim.scene``) is a floor plan, the clutter the LiDAR sees but the plan lacks and
named trajectories. Two buildings (``sim.buildings``), one per regime of the paper
(Section IV): ``three_rooms`` (three similar, non-congruent rooms: multimodal aliases) and
``symmetric_bays`` (four congruent bays at a 7.30 m pitch: a translational lattice).
"""

from __future__ import annotations

from collections.abc import Callable

from mfcl_jax.sim.buildings import BAY_PITCH, symmetric_bays, three_rooms
from mfcl_jax.sim.scene import Scene, rect_segments
from mfcl_jax.sim.world3d import DEFAULT_CLUTTER_HEIGHT

__all__ = [
    "Scene",
    "DEFAULT_CLUTTER_HEIGHT",
    "three_rooms",
    "symmetric_bays",
    "SCENES",
    "get_scene",
    "rect_segments",
    "BAY_PITCH",
]

SCENES: dict[str, Callable[[], Scene]] = {
    "three_rooms": three_rooms,
    "symmetric_bays": symmetric_bays,
}


def get_scene(name: str) -> Scene:
    """Builds the registered scene ``name``.

    Raises:
        KeyError: for an unknown name; the message lists the known ones.
    """
    try:
        factory = SCENES[name]
    except KeyError:
        raise KeyError(f"unknown scene {name!r}; known scenes: {sorted(SCENES)}") from None
    return factory()
