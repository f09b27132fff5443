"""Procedural building families: many seeded buildings the localizer has never seen.

``make_scene(family, seed)`` builds a ``Scene`` (floor plan, furniture, at least three walks)
deterministically from the family name and a seed. The families, each a regime of aliasing:

* ``plain``: 4-9 rooms of random sizes (maybe an L-shaped one): the easy case;
* ``bays``: 3-6 congruent bays along a corridor (translational symmetry);
* ``offices``: 8-20 near-identical small offices along one or two corridors;
* ``corridor``: a long featureless corridor with few or no side openings;
* ``hall``: an open hall on a regular column grid;
* ``ring``: a ring corridor (one room with a hole) round a core;
* ``rotational``: a cross or a loop with 2-fold or 4-fold rotational symmetry;
* ``mirror``: a wing and its mirror image joined by a lobby.

Faults turn a scene into a new one where reality and plan disagree (``with_clutter``,
``with_as_built``, ``with_scale_error``); ``write_family_geojson`` writes it
(``report.plots_scene.plot_family`` draws it).
"""

from __future__ import annotations

import numpy as np

from mfcl_jax.sim.families.asbuilt import AS_BUILT_KINDS, NotApplicable, with_as_built
from mfcl_jax.sim.families.common import family_rng
from mfcl_jax.sim.families.corridors import bays, corridor
from mfcl_jax.sim.families.faults import (
    PLAN_FORMATS,
    with_clutter,
    with_plan_format,
    with_scale_error,
)
from mfcl_jax.sim.families.halls import hall
from mfcl_jax.sim.families.mirror import mirror
from mfcl_jax.sim.families.nearsym import NEAR_SYM_KINDS, with_near_symmetry
from mfcl_jax.sim.families.offices import offices
from mfcl_jax.sim.families.output import write_family_geojson
from mfcl_jax.sim.families.rings import ring
from mfcl_jax.sim.families.rooms import plain
from mfcl_jax.sim.families.rotational import rotational
from mfcl_jax.sim.scenes import Scene

__all__ = [
    "FAMILIES",
    "AS_BUILT_KINDS",
    "NotApplicable",
    "make_scene",
    "with_clutter",
    "with_as_built",
    "with_near_symmetry",
    "NEAR_SYM_KINDS",
    "with_scale_error",
    "with_plan_format",
    "PLAN_FORMATS",
    "write_family_geojson",
]

_BUILDERS = {
    "plain": plain,
    "bays": bays,
    "offices": offices,
    "corridor": corridor,
    "hall": hall,
    "ring": ring,
    "rotational": rotational,
    "mirror": mirror,
}
FAMILIES: tuple[str, ...] = tuple(_BUILDERS)


def make_scene(family: str, seed: int) -> Scene:
    """Builds building ``seed`` of ``family`` (the same arrays for the same arguments).

    Args:
        family: one of ``FAMILIES``.
        seed: a non-negative integer.

    Returns:
        A ``Scene`` named ``f"{family}-{seed}"`` with walks ``"A"``, ``"B"``, ``"C"``.

    Raises:
        ValueError: an unknown family (the message lists the known ones) or a bad seed.
    """
    if family not in _BUILDERS:
        raise ValueError(f"unknown family {family!r}; known families: {', '.join(FAMILIES)}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"family {family!r}: seed must be a non-negative integer, got {seed!r}")
    return _BUILDERS[family](family_rng(family, int(seed)), f"{family}-{int(seed)}")
