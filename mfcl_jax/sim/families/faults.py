"""Clutter and plan-scale faults: each returns a NEW ``Scene`` and changes only what it says.

* ``with_clutter``: more furniture (the LiDAR's world), plan and walks untouched.
* ``with_scale_error``: the plan (what the robot is given) is scaled about its centre; the world
  (real walls, clutter) and the walks stay true to scale.
* ``with_plan_format``: the plan as many exports give it: without its door features
  (``no_doors``), or rooms only, without walls and doors (``rooms_only``); the world is
  unchanged.

As-built deviations of the walls are in ``asbuilt``. Apply ``with_clutter`` and
``with_as_built`` before ``with_scale_error``: both read the plan's rooms and doors as the
true ones.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from shapely import affinity

from mfcl_jax.floorplan.model import Door, Floorplan, Room
from mfcl_jax.sim.families.asbuilt import seeded
from mfcl_jax.sim.families.clutter import furnish
from mfcl_jax.sim.world3d import DEFAULT_CLUTTER_HEIGHT

__all__ = ["with_clutter", "with_scale_error", "with_plan_format", "PLAN_FORMATS"]

PLAN_FORMATS = ("no_doors", "rooms_only")


def with_clutter(scene, area_fraction: float, seed: int):
    """Adds furniture covering about ``area_fraction`` of the floor, >= 0.5 m from every walk.

    Args:
        scene: a ``Scene``.
        area_fraction: target fraction of the rooms' floor area, in ``[0, 0.5]``.
        seed: non-negative integer.

    Returns:
        The scene with the new items appended to its clutter; its description ends with the
        fraction actually covered (less than asked where the walks leave too little room).
    """
    if not (isinstance(area_fraction, int | float) and 0.0 <= area_fraction <= 0.5):
        raise ValueError(f"with_clutter: area_fraction must be in [0, 0.5], got {area_fraction!r}")
    rng = seeded("with_clutter", scene, seed)
    items, got = furnish(
        scene.floorplan,
        scene.trajectories.values(),
        float(area_fraction),
        rng,
        world=scene.as_built,
        existing=scene.clutter,
    )
    extra = np.full(len(items), DEFAULT_CLUTTER_HEIGHT)
    return dataclasses.replace(
        scene,
        clutter=np.concatenate([scene.clutter, items]),
        clutter_height=np.concatenate([scene.clutter_height, extra]),
        description=(
            f"{scene.description}; clutter +{got:.3f} of the floor (asked {area_fraction:.3f})"
        ),
    )


def with_scale_error(scene, factor: float):
    """The plan scaled by ``factor`` about its centre; the world and the walks stay true.

    Args:
        scene: a ``Scene``.
        factor: scale of the plan (e.g. 1.01-1.02 for a 1-2 % drawing error), finite, > 0.

    Returns:
        The scene with the scaled plan and ``as_built`` set to the true wall faces, so that
        ``Scene.segments`` (what the LiDAR sees) is unchanged.
    """
    if not (isinstance(factor, int | float) and math.isfinite(factor) and factor > 0):
        raise ValueError(f"with_scale_error: factor must be a finite number > 0, got {factor!r}")
    fp = scene.floorplan
    x0, y0, x1, y1 = fp.bounds
    c = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    f = float(factor)

    def geom(g):
        return affinity.scale(g, f, f, origin=(c[0], c[1]))

    plan = Floorplan(
        walls=c + f * (fp.walls - c),
        thickness=f * fp.thickness,
        rooms=tuple(Room(r.name, geom(r.polygon)) for r in fp.rooms),
        doors=tuple(Door(c + f * (np.asarray(d.segment) - c), d.rooms) for d in fp.doors),
        wall_polygons=tuple(geom(p) for p in fp.wall_polygons),
        name=fp.name,
        source=f"{fp.source} scaled x{f:g}",
    )
    return dataclasses.replace(
        scene,
        floorplan=plan,
        as_built=fp.wall_faces if scene.as_built is None else scene.as_built,
        description=f"{scene.description}; plan scale error x{f:g}",
    )


def with_plan_format(scene, fmt: str):
    """The plan without its doors (``no_doors``) or with its rooms only (``rooms_only``:
    no walls, no doors; ``Floorplan`` draws walls along the rooms' free boundaries). The world
    (the walls the LiDAR sees, clutter) and the walks are unchanged.

    Args:
        scene: a ``Scene``.
        fmt: one of ``PLAN_FORMATS``.
    """
    if fmt not in PLAN_FORMATS:
        raise ValueError(f"with_plan_format: fmt must be one of {PLAN_FORMATS}, got {fmt!r}")
    fp = scene.floorplan
    if fmt == "no_doors":
        plan = Floorplan(walls=fp.walls, thickness=fp.thickness, rooms=fp.rooms,
                         wall_polygons=fp.wall_polygons, name=fp.name,
                         source=f"{fp.source} without doors")  # fmt: skip
    else:
        plan = Floorplan(walls=np.zeros((0, 2, 2)), thickness=0.1, rooms=fp.rooms, name=fp.name,
                         source=f"{fp.source} rooms only")  # fmt: skip
    return dataclasses.replace(
        scene,
        floorplan=plan,
        as_built=fp.wall_faces if scene.as_built is None else scene.as_built,
        description=f"{scene.description}; plan {fmt.replace('_', ' ')}",
    )
