"""Results a person can look at: ``mfcl localize --viz run.mcap`` (read back with the MCAP
library's own reader) and ``mfcl evaluate --plot fig.png``; bad output paths refused before
any work (exit 2, a message naming the path, nothing written)."""

from __future__ import annotations

import base64
import contextlib
import io
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
import shapely
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from shapely.geometry import box

from mfcl_jax.cli import main
from mfcl_jax.floorplan import Door, Floorplan, Room, save_geojson
from mfcl_jax.floorplan.load import load_floorplan
from mfcl_jax.io import DataError, read_decisions
from mfcl_jax.robot import status
from mfcl_jax.robot.viz import FRAME, SCHEMAS, TOPICS, VizWriter
from mfcl_jax.sim.scenes import get_scene

MAGIC = b"\x89MCAP0\r\n"
# The walk of tests/test_cli.py along rooms 209 -> 208 -> 207: 11 windows of 6 m, the last ones
# COMMIT (what the layer decides before is its business: AMBIGUOUS windows are checked when
# there are some, and always in the writer's own test below).
WAYPOINTS = [(37.4, 6.4), (34.0, 7.2), (31.0, 8.6), (26.0, 8.6), (21.0, 6.2), (16.2, 8.6),
             (11.6, 8.6)]  # fmt: skip


# ----------------------------------------------------------------------------- reading back
def _read(path) -> dict:
    """Every message by topic as ``(log_time, schema name, decoded JSON)``, after checking
    that the file is complete: magic at both ends, a summary whose counts match."""
    data = path.read_bytes()
    assert data.startswith(MAGIC) and data.endswith(MAGIC)
    with open(path, "rb") as f:
        assert sum(1 for _ in StreamReader(f).records) > 0  # parses to the footer
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        out: dict[str, list] = {t: [] for t in TOPICS}
        for schema, channel, msg in reader.iter_messages(log_time_order=True):
            assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
            assert json.loads(schema.data) == SCHEMAS[schema.name]
            out[channel.topic].append((msg.log_time, schema.name, json.loads(msg.data)))
    assert summary.statistics.message_count == sum(len(v) for v in out.values())
    names = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert names == TOPICS
    return out


def _cloud(msg) -> np.ndarray:
    """The points of a ``foxglove.PointCloud`` message, placed by its pose: ``(n, 2)``."""
    assert msg["point_stride"] == 8 and [f["name"] for f in msg["fields"]] == ["x", "y"]
    pts = np.frombuffer(base64.b64decode(msg["data"]), "<f4").reshape(-1, 2).astype(float)
    p, q = msg["pose"]["position"], msg["pose"]["orientation"]
    yaw = 2 * math.atan2(q["z"], q["w"])
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = pts[:, 0], pts[:, 1]
    return np.stack([p["x"] + c * x - s * y, p["y"] + s * x + c * y], 1)


def _xyyaw(pose) -> list[float]:
    p, q = pose["position"], pose["orientation"]
    return [p["x"], p["y"], math.degrees(2 * math.atan2(q["z"], q["w"]))]


def _no_leftovers(folder) -> None:
    assert not [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]


# ----------------------------------------------------------------------------- the CLI run
@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One simulated walk, localized once with ``--viz`` (the only localize run here)."""
    root = tmp_path_factory.mktemp("viz")
    plan = root / "three.geojson"
    save_geojson(get_scene("three_rooms").floorplan, plan)
    wp = root / "wp.csv"
    wp.write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in WAYPOINTS) + "\n")
    ds, dec, viz = root / "ds", root / "dec.jsonl", root / "out" / "run.mcap"
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        argv = ["simulate", "--floorplan", str(plan), "--trajectory", str(wp), "--out", str(ds)]
        assert main([*argv, "--seed", "3"]) == 0
        assert main(["localize", str(ds), "--out", str(dec), "--viz", str(viz), "--quiet"]) == 0
    assert f"viz: {viz}" in sink.getvalue()
    return SimpleNamespace(root=root, ds=ds, dec=dec, viz=viz)


def test_viz_reads_back(run):
    msgs = _read(run.viz)
    decs = read_decisions(run.dec)
    states = [d["state"] for d in decs]
    assert len(decs) == 11 and states[-1] == "COMMIT"
    assert len(msgs["/mfcl/plan"]) == 1
    for topic in TOPICS:
        if topic != "/mfcl/plan":
            assert len(msgs[topic]) == len(decs), topic
    # One timeline: each window's messages at its time t; the plan first.
    times = [round(d["t"] * 1e9) for d in decs]
    for topic in TOPICS:
        if topic != "/mfcl/plan":
            assert [m[0] for m in msgs[topic]] == times, topic
    assert msgs["/mfcl/plan"][0][0] <= times[0]
    assert [m[2] for m in msgs["/mfcl/decision"]] == decs
    for (_, _, log), d in zip(msgs["/mfcl/state"], decs, strict=True):
        assert log["message"] == status.status_line(d) and log["name"] == "mfcl"
    # The plan: walls, rooms, doors in the plan frame, every room named.
    fp = load_floorplan(run.ds / "floorplan.geojson")
    (entity,) = msgs["/mfcl/plan"][0][2]["entities"]
    assert entity["frame_id"] == FRAME and len(entity["lines"]) == 3
    walls = np.asarray([[p["x"], p["y"]] for p in entity["lines"][0]["points"]])
    np.testing.assert_allclose(walls.reshape(-1, 2, 2), fp.wall_faces + fp.offset)
    assert sorted(t["text"] for t in entity["texts"]) == sorted(fp.room_names)
    x0, y0, x1, y1 = fp.bounds
    for (_, _, cloud), (_, _, pose), (_, _, path), (_, _, alt), d in zip(
        msgs["/mfcl/scan"], msgs["/mfcl/pose"], msgs["/mfcl/path"], msgs["/mfcl/alternatives"],
        decs, strict=True,
    ):  # fmt: skip
        pts = _cloud(cloud)
        assert cloud["frame_id"] == pose["frame_id"] == path["frame_id"] == FRAME
        if d["state"] != "COMMIT":
            assert len(pts) == len(pose["poses"]) == len(path["poses"]) == 0
        else:  # the window's scans, placed at the committed anchor, lie on the plan's walls
            assert len(pts) > 50
            assert np.all((pts >= [x0 - 0.5, y0 - 0.5]) & (pts <= [x1 + 0.5, y1 + 0.5]))
            dist = shapely.distance(fp.wall_solid, shapely.points(pts))
            assert np.median(dist) < 0.1, np.median(dist)
            want = [d["pose"]["x"], d["pose"]["y"], d["pose"]["yaw_deg"]]
            np.testing.assert_allclose(_xyyaw(pose["poses"][0]), want, atol=1e-6)
            # the anchored path: every window so far, the newest at the robot's pose
            assert len(path["poses"]) == d["k"]
            np.testing.assert_allclose(_xyyaw(path["poses"][-1]), want, atol=1e-6)
        got = [_xyyaw(p) for p in alt["poses"]]
        want = [[a["x"], a["y"], a["yaw_deg"]] for a in d["alternatives"] or []]
        assert len(got) == len(want) and (d["state"] == "AMBIGUOUS") == bool(want)
        if want:
            np.testing.assert_allclose(got, want, atol=1e-6)
    _no_leftovers(run.viz.parent)


def test_evaluate_plot(run, capsys):
    from PIL import Image

    from mfcl_jax.report.plots_run import DPI, figure_size

    png = run.root / "figs" / "eval.png"
    assert main(["evaluate", str(run.ds), "--decisions", str(run.dec), "--plot", str(png)]) == 0
    assert f"figure: {png}" in capsys.readouterr().out
    w, h = figure_size(load_floorplan(run.ds / "floorplan.geojson"))
    with Image.open(png) as im:
        assert im.format == "PNG" and im.size == (round(w * DPI), round(h * DPI))
        rgb = np.asarray(im.convert("RGB"), int)
    # the commit is correct: the odometry it places is drawn green (tab:green)
    green = np.all(np.abs(rgb - [44, 160, 44]) < 30, -1)
    assert green.sum() > 50
    _no_leftovers(png.parent)


# ----------------------------------------------------------------------------- refusals
def _refused(argv, capsys, name) -> str:
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mfcl: error:") and str(name) in err and "Traceback" not in err
    return err


@pytest.mark.parametrize("bad", ["folder", "suffix", "under_file", "input_folder", "same_as_out"])
def test_bad_viz_path(run, tmp_path, capsys, bad):
    out = tmp_path / "dec.jsonl"
    (tmp_path / "file").write_text("x")
    (tmp_path / "dir.mcap").mkdir()
    viz = {
        "folder": tmp_path / "dir.mcap",
        "suffix": tmp_path / "run.json",
        "under_file": tmp_path / "file" / "run.mcap",
        "input_folder": run.ds / "scans" / "run.mcap",
        "same_as_out": tmp_path / "run.mcap",
    }[bad]
    if bad == "same_as_out":
        out = viz
    before = sorted(p.name for p in tmp_path.iterdir())
    _refused(["localize", run.ds, "--out", out, "--viz", viz], capsys, viz)
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no decisions, no viz
    assert list((tmp_path / "dir.mcap").iterdir()) == []
    assert not (run.ds / "scans" / "run.mcap").exists()


def test_viz_refused_for_several_datasets_and_checked_with_follow(run, tmp_path, capsys):
    viz = tmp_path / "run.mcap"
    err = _refused(["localize", run.ds, tmp_path, "--out-dir", tmp_path, "--viz", viz], capsys, viz)
    assert "one at a time" in err
    _refused(["localize", "--follow", run.ds, "--viz", tmp_path / "run.txt"], capsys, "run.txt")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("bad", ["folder", "suffix", "under_file", "is_input", "no_plan"])
def test_bad_plot_path(run, tmp_path, capsys, bad):
    (tmp_path / "file").write_text("x")
    (tmp_path / "dir.png").mkdir()
    dec, png, extra = run.dec, tmp_path / "fig.png", []
    named = {
        "folder": tmp_path / "dir.png",
        "suffix": tmp_path / "fig.txt",
        "under_file": tmp_path / "file" / "fig.png",
        "is_input": tmp_path / "dec.png",  # the decisions file itself, under a figure's name
        "no_plan": tmp_path / "missing.geojson",
    }[bad]
    if bad == "is_input":
        dec = named
        dec.write_bytes(run.dec.read_bytes())
    if bad == "no_plan":
        extra = ["--floorplan", named]
    else:
        png = named
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    _refused(["evaluate", run.ds, "--decisions", dec, "--plot", png, *extra], capsys, named)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before
    assert list((tmp_path / "dir.png").iterdir()) == []


# ----------------------------------------------------------------------------- the writer
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
    """A ``WindowResult``-like window and its record (``status.record``, anchors local);
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
    rec = status.record(d, X, "", offset, X, best, rival)
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
