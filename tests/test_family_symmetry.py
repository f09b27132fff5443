"""Procedural building families: the symmetries each family is built with (translated bays,
rotations, a mirror) and the shapes of their rooms."""

from __future__ import annotations

import numpy as np
import pytest
from shapely import affinity

from mfcl_jax.sim.families import FAMILIES, make_scene
from tests._families import SEEDS, _centre, _same_region, all_scenes


@pytest.fixture(scope="module")
def scenes():
    return all_scenes()


def _rot_maps(fp, deg) -> bool:
    solid = fp.wall_solid
    return _same_region(affinity.rotate(solid, deg, origin=_centre(fp)), solid)


def _mirror_maps(fp) -> bool:
    solid = fp.wall_solid
    return _same_region(affinity.scale(solid, -1.0, 1.0, origin=_centre(fp)), solid)


def test_bays_are_exact_translated_copies(scenes):
    for s in SEEDS:
        fp = scenes["bays", s].floorplan
        bays = [r.polygon for r in fp.rooms if r.name.startswith("B")]
        assert 3 <= len(bays) <= 6
        c = np.array([[p.centroid.x, p.centroid.y] for p in bays])
        pitch = np.diff(c[:, 0])
        np.testing.assert_allclose(pitch, pitch[0], atol=1e-9)
        np.testing.assert_allclose(c[:, 1], c[0, 1], atol=1e-9)
        for p, ck in zip(bays, c, strict=True):
            moved = affinity.translate(p, *(c[0] - ck))
            iou = moved.intersection(bays[0]).area / moved.union(bays[0]).area
            assert iou > 1 - 1e-9
        # Doors at the same place in every bay.
        doors = [d for d in fp.doors if any(r.startswith("B") for r in d.rooms)]
        rel = [d.segment.mean(0) - c[k] for k, d in enumerate(doors)]
        np.testing.assert_allclose(np.asarray(rel) - rel[0], 0.0, atol=1e-9)


def test_rotational_symmetry_as_described():
    seen = set()
    for s in range(16):
        sc = make_scene("rotational", s)
        fp, desc = sc.floorplan, sc.description
        fold = 4 if "4-fold" in desc else 2
        exact = desc.endswith("exact")
        seen.add((fold, exact, "cross" if "cross" in desc else "loop"))
        assert _rot_maps(fp, 360 / fold) == exact, sc.name
        if exact:
            assert _rot_maps(fp, 180)
            assert _rot_maps(fp, 90) == (fold == 4), sc.name
            assert not _mirror_maps(fp), sc.name  # rotations only, no mirror
    assert {(f, e) for f, e, _ in seen} == {(2, True), (2, False), (4, True), (4, False)}
    assert {lay for *_, lay in seen} == {"cross", "loop"}


def test_mirror_maps_onto_itself_but_not_by_a_half_turn(scenes):
    for s in SEEDS:
        fp = scenes["mirror", s].floorplan
        assert _mirror_maps(fp) and not _rot_maps(fp, 180), fp.name
        for room in fp.rooms:
            if room.name.startswith("E"):
                twin = fp.room("W" + room.name[1:]).polygon
                assert _same_region(affinity.scale(room.polygon, -1.0, 1.0, origin=(0, 0)), twin)


def test_family_shapes(scenes):
    for s in SEEDS:
        fp = {f: scenes[f, s].floorplan for f in FAMILIES}
        assert 4 <= len(fp["plain"].rooms) <= 9
        offices = [r.polygon.area for r in fp["offices"].rooms if r.name.startswith("O")]
        assert 8 <= len(offices) <= 20 and max(offices) / min(offices) < 1.08
        ring = fp["ring"].room("K").polygon
        assert len(ring.interiors) == 1  # the ring corridor is one room with a hole
        x0, y0, x1, y1 = fp["corridor"].room("C").polygon.bounds
        assert 29.5 <= x1 - x0 <= 60.0 and 1.8 - 1e-9 <= y1 - y0 <= 3.0 + 1e-9
        hall = fp["hall"].room("H").polygon
        hx0, hy0, hx1, hy1 = hall.bounds
        assert len(hall.interiors) >= 4 and 19.5 <= min(hx1 - hx0, hy1 - hy0) <= 40
