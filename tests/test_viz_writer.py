"""``VizWriter`` on its own: scans, path and alternatives placed in the plan frame (offset,
segments), its edge cases, and schemas that Foxglove's parser accepts."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from shapely.geometry import box

from mfcl_jax.floorplan import Door, Floorplan, Room
from mfcl_jax.io import DataError
from mfcl_jax.robot import records
from mfcl_jax.robot.viz import SCHEMAS, TOPICS, VizWriter
from tests._mcap import _cloud, _no_leftovers, _read, _xyyaw


def _plan(offset=(0.0, 0.0)) -> Floorplan:
    corners = np.array([[0, 0], [8, 0], [8, 4], [0, 4]], float)
    walls = np.stack([corners, np.roll(corners, -1, 0)], 1)
    return Floorplan(
        walls=walls,
        thickness=0.15,
        rooms=(Room("a", box(0, 0, 4, 4)), Room("b", box(4, 0, 8, 4))),
        doors=(Door(np.array([[4, 1.5], [4, 2.5]]), ("a", "b")),),
        offset=np.asarray(offset, float),
    )


def _compose(a, b) -> np.ndarray:
    """``a b``: poses ``b (n, 3)`` (or points ``(n, 2)``) moved by the pose ``a``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    b = np.atleast_2d(np.asarray(b, float))
    xy = np.stack([a[0] + c * b[:, 0] - s * b[:, 1], a[1] + s * b[:, 0] + c * b[:, 1]], 1)
    return np.concatenate([xy, a[2] + b[:, 2:]], 1)


def _window(k, t, X, state, anchor=None, rival=None, segment=0, offset=(0.0, 0.0), seen=None):
    """A ``WindowResult``-like window and its record (``records.record``, anchors local);
    ``seen``: plan points (local frame) that the robot at ``anchor X`` sees."""
    a, points = None, None
    if state == "COMMIT":
        a = {"x": anchor[0], "y": anchor[1], "yaw_deg": math.degrees(anchor[2])}
    if seen is not None:  # the points in the window's frame S_k: (anchor X)^-1 seen
        x, y, yaw = _compose(anchor, [X])[0]
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = seen[:, 0] - x, seen[:, 1] - y
        points = np.stack([c * dx + s * dy, -s * dx + c * dy], 1)
    d = dict(k=k, t=t, state=state, anchor=a, symmetry=None, tau=None, B1=3, B2=0, margin=3)
    best = anchor if state == "AMBIGUOUS" else None
    rec = records.record(d, X, "", offset, X, best, rival)
    return SimpleNamespace(k=k, t=t, X=np.asarray(X), segment=segment, points=points), rec


def test_writer_places_scans_path_and_alternatives_in_the_plan_frame(tmp_path):
    off = np.array([1000.0, -2000.0])  # plan = local + offset (a georeferenced plan)
    fp = _plan(off)
    A = (0.7, 0.4, 0.3)  # the anchor T* (local frame)
    Xs = [(0.0, 0.0, 0.0), (1.0, 0.2, 0.1), (2.0, 0.5, -0.2), (0.5, 0.5, 0.4), (1.5, 0.5, 0.4)]
    # The robot at T* X_k sees the wall y = 0: its points in the window frame S_k.
    wall = np.stack([np.linspace(1, 7, 40), np.zeros(40)], 1)
    path = tmp_path / "v.mcap"
    viz = VizWriter(path, fp, start=1.0)
    kw = dict(anchor=A, offset=off)
    windows = [
        _window(1, 2.0, Xs[0], "DEFER", offset=off),
        _window(2, 3.0, Xs[1], "AMBIGUOUS", rival=(5.0, 3.0, math.pi), **kw),
        _window(3, 4.0, Xs[2], "COMMIT", seen=wall, **kw),
        _window(4, 5.0, Xs[3], "DEFER", segment=1, offset=off),  # an odometry restart
        _window(5, 6.0, Xs[4], "COMMIT", segment=1, seen=wall, **kw),
    ]
    for r, rec in windows:
        viz.add(r, rec)
    assert viz.n_windows == 5 and not path.exists()  # nothing on disk before close
    assert viz.close() == path
    msgs = _read(path)
    assert msgs["/mfcl/plan"][0][0] == 1_000_000_000  # at the start given
    (entity,) = msgs["/mfcl/plan"][0][2]["entities"]
    doors = np.asarray([[p["x"], p["y"]] for p in entity["lines"][2]["points"]])
    np.testing.assert_allclose(doors, [[4, 1.5], [4, 2.5]] + off)
    clouds = [_cloud(m[2]) for m in msgs["/mfcl/scan"]]
    assert [len(c) for c in clouds] == [0, 0, 40, 0, 40]
    for c in (clouds[2], clouds[4]):
        np.testing.assert_allclose(c, wall + off, atol=1e-4)
    paths = [m[2]["poses"] for m in msgs["/mfcl/path"]]
    assert [len(p) for p in paths] == [0, 0, 3, 0, 2]  # the segment's windows only
    got = np.asarray([_xyyaw(p)[:2] for p in paths[2]])
    np.testing.assert_allclose(got, _compose(A, Xs[:3])[:, :2] + off, atol=1e-9)
    got = np.asarray([_xyyaw(p)[:2] for p in paths[4]])
    np.testing.assert_allclose(got, _compose(A, Xs[3:])[:, :2] + off, atol=1e-9)
    alts = [m[2]["poses"] for m in msgs["/mfcl/alternatives"]]
    assert [len(a) for a in alts] == [0, 2, 0, 0, 0]
    np.testing.assert_allclose(_xyyaw(alts[1][0])[:2], _compose(A, [Xs[1]])[0, :2] + off)
    levels = [m[2]["level"] for m in msgs["/mfcl/state"]]
    assert levels == [2, 3, 2, 2, 2]  # INFO, WARNING for AMBIGUOUS


def test_writer_edges(tmp_path):
    fp = _plan()
    with pytest.raises(DataError, match=r"v\.mcap: the first scan is at t=-1"):
        VizWriter(tmp_path / "v.mcap", fp, start=-1.0)
    viz = VizWriter(tmp_path / "v.mcap", fp)
    r, rec = _window(7, float("nan"), (0, 0, 0), "DEFER")
    with pytest.raises(DataError, match="window k=7 is at t=nan"):
        viz.add(r, rec)
    viz.discard()  # an interrupted run: nothing written
    assert list(tmp_path.iterdir()) == []
    only_plan = VizWriter(tmp_path / "empty.mcap", fp).close()  # no window: the plan alone
    msgs = _read(only_plan)
    assert len(msgs["/mfcl/plan"]) == 1 and sum(len(v) for v in msgs.values()) == 1
    with pytest.raises(RuntimeError, match="already closed"):
        viz.close()
    _no_leftovers(tmp_path)


def _foxglove_parses(schema: dict, where: str) -> None:
    """What Foxglove's JSON-schema parser (``@foxglove/mcap-support``) accepts: an object
    whose properties each have a type (or a oneOf of numeric constants), arrays with a typed
    item, strings plain or base64."""
    assert schema["type"] == "object", where
    for name, field in schema["properties"].items():
        at = f"{where}.{name}"
        if "oneOf" in field:
            assert all(isinstance(o["const"], int) for o in field["oneOf"]), at
        elif field["type"] == "object":
            _foxglove_parses(field, at)
        elif field["type"] == "array":
            item = field["items"]
            assert item["type"] in ("boolean", "string", "number", "integer", "object"), at
            assert "contentEncoding" not in item, at
            if item["type"] == "object":
                _foxglove_parses(item, at)
        else:
            assert field["type"] in ("boolean", "string", "number", "integer"), at
            assert field.get("contentEncoding") in (None, "base64"), at


def test_schemas_parse_as_foxglove_does():
    for name, schema in SCHEMAS.items():
        _foxglove_parses(schema, name)
    assert set(TOPICS.values()) == set(SCHEMAS)
    assert SCHEMAS["foxglove.PointCloud"]["properties"]["data"]["contentEncoding"] == "base64"
