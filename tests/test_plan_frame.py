"""Plans far from the origin: loaded in float64, moved to a local origin (``offset``), the
same rasters and features as the plan near the origin, and anchors written back in the
plan's frame with full precision."""

from __future__ import annotations

import json

import jax
import numpy as np
import pytest
from shapely.geometry import box

from mfcl_jax.floorplan import (
    Door,
    Floorplan,
    Room,
    load_floorplan,
    local_origin,
    save_geojson,
    shift_plan,
    to_plan_frame,
)


def dyadic_plan() -> Floorplan:
    """Coordinates in 1/8 m: exact in float64 at 1e7, so shifts are exact."""
    walls = np.array(
        [
            [[0, 0], [10, 0]],
            [[10, 0], [10, 8]],
            [[10, 8], [0, 8]],
            [[0, 8], [0, 0]],
            [[5, 0], [5, 3.5]],
            [[5, 4.5], [5, 8]],
            [[7.5, 0], [7.5, 2.25]],
        ],
        float,
    )
    rooms = (Room("a", box(0.125, 0.125, 4.875, 7.875)), Room("b", box(5.125, 0.125, 9.875, 7.875)))
    doors = (Door(np.array([[5, 3.5], [5, 4.5]]), ("a", "b")),)
    return Floorplan(walls=walls, thickness=0.25, rooms=rooms, doors=doors, name="dy")


SHIFTS = [(1e7, 1e7), (500000.0, 5e6)]


@pytest.mark.parametrize("shift", SHIFTS, ids=["1e7", "utm"])
def test_far_plan_gives_the_same_rasters_and_features(tmp_path, shift):
    from mfcl_jax.frontend import FrontendParams, build_features

    near = dyadic_plan()
    far_file = save_geojson(near.transformed((*shift, 0.0)), tmp_path / "far.geojson")
    coords = json.loads(far_file.read_text())["features"][0]["geometry"]["coordinates"]
    assert coords[0] == [shift[0], shift[1]]  # the file holds the georeferenced plan
    fp = load_floorplan(far_file)
    np.testing.assert_array_equal(fp.offset, shift)
    assert fp.offset.dtype == np.float64
    np.testing.assert_array_equal(fp.walls, near.walls)
    r_near, r_far = near.rasterize(), fp.rasterize()
    for name in ("origin", "dist", "wall", "room_id", "inside", "adjacency", "room_centroids"):
        np.testing.assert_array_equal(getattr(r_far, name), getattr(r_near, name), err_msg=name)
    f_near = build_features(near, FrontendParams())
    f_far = build_features(fp, FrontendParams())
    same = jax.tree.map(lambda a, b: bool(np.array_equal(a, b, equal_nan=True)), f_near, f_far)
    assert all(jax.tree.leaves(same))
    # Saving writes the plan frame again: a round trip keeps the georeferenced coordinates.
    again = json.loads(save_geojson(fp, tmp_path / "again.geojson").read_text())
    assert again["features"][0]["geometry"]["coordinates"][0] == [shift[0], shift[1]]


def test_decimal_plan_far_away_gives_the_same_rasters(tmp_path):
    """Coordinates in decimal metres (11.35) cannot be held exactly at 5e6 m; the loader's
    rounding to 10 nm gives back the plan drawn near the origin, cell for cell."""
    from mfcl_jax.sim.scenes import get_scene

    plan = get_scene("three_rooms").floorplan
    near = load_floorplan(save_geojson(plan, tmp_path / "near.geojson"))
    far = load_floorplan(
        save_geojson(plan.transformed((500000.0, 5e6, 0.0)), tmp_path / "f.geojson")
    )
    assert far.bounds == near.bounds and np.array_equal(far.walls, near.walls)
    r_near, r_far = near.rasterize(), far.rasterize()
    for name in ("origin", "dist", "wall", "room_id", "inside"):
        np.testing.assert_array_equal(getattr(r_far, name), getattr(r_near, name), err_msg=name)


def test_offset_rule_and_precision():
    near = dyadic_plan()
    assert local_origin(near) is near and not near.offset.any()
    odd = near.transformed((500123.375, 5000456.25, 0.0))
    fp = local_origin(odd)
    np.testing.assert_array_equal(fp.offset, [500000.0, 5000000.0])  # centre, rounded to 1 km
    np.testing.assert_array_equal(to_plan_frame(fp.walls, fp.offset), odd.walls)
    assert np.abs(fp.walls).max() < 1000
    back = shift_plan(fp, -fp.offset)
    np.testing.assert_array_equal(back.walls, odd.walls)
    assert not back.offset.any()
    # An anchor survives the round trip to the millimetre and beyond.
    pose = np.array([123.456789, -45.0000001, 0.3])
    plan = to_plan_frame(pose, fp.offset)
    assert plan[0] == 500123.456789 and plan[1] == 5000000 - 45.0000001 and plan[2] == 0.3
    text = json.dumps({"x": float(plan[0])})
    assert json.loads(text)["x"] == plan[0]


class _StubLocalizer:
    """Stands in for the JAX localizer: commits to the first room's centroid in the frame of
    the plan it is given (what a real localizer does up to its error)."""

    def __init__(self, fp, params=None):
        self.fp = fp
        self.params = params

    def estimate(self, seq):
        return 2

    def run(self, seq):
        from mfcl_jax.decision import Decision
        from mfcl_jax.robot.localizer import WindowResult

        cx, cy = (float(v) for v in self.fp.room_centroids[0])
        zero = {f: np.zeros((), np.int32) for f in Decision.__dataclass_fields__}
        for k in (1, 2):
            d = Decision(**{**zero, "state": np.int32(2 if k == 2 else 0),
                            "anchor": np.array([cx + 0.123456789, cy, 0.25]),
                            "tau": np.zeros(2), "b1": np.int32(3), "margin": np.int32(3),
                            "competitor": np.zeros(3), "alias_motion": np.zeros(3)})  # fmt: skip
            yield WindowResult(k, d, 0, 0, float(k), np.zeros(3), 0, 0.1, 0, 0, False,
                               np.zeros(3))  # fmt: skip


@pytest.mark.parametrize("shift", SHIFTS, ids=["1e7", "utm"])
def test_cli_writes_anchors_in_the_plan_frame(tmp_path, monkeypatch, capsys, shift):
    from importlib import import_module

    from mfcl_jax.cli import main
    from mfcl_jax.io import read_decisions
    from mfcl_jax.sources import write_dataset

    # (the package re-exports a function named `localize`: fetch the module itself)
    monkeypatch.setattr(import_module("mfcl_jax.robot.localizer"), "Localizer", _StubLocalizer)
    near = dyadic_plan()
    t = [0.0, 1.0]
    ds = write_dataset(tmp_path / "ds", near, t, [np.ones((3, 2))] * 2, np.zeros((2, 3)))
    far = save_geojson(near.transformed((*shift, 0.0)), tmp_path / "far.geojson")
    assert main(["localize", str(ds), "--out", str(tmp_path / "near.jsonl")]) == 0
    argv = ["localize", str(ds), "--floorplan", str(far), "--out", str(tmp_path / "far.jsonl")]
    assert main(argv) == 0
    assert "local frame" in capsys.readouterr().err
    a_near = read_decisions(tmp_path / "near.jsonl")[1]["anchor"]
    a_far = read_decisions(tmp_path / "far.jsonl")[1]["anchor"]
    assert a_far["x"] == a_near["x"] + shift[0] and a_far["y"] == a_near["y"] + shift[1]
    assert a_far["yaw_deg"] == a_near["yaw_deg"]
