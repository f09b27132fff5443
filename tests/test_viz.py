"""Results a person can look at: ``mfcl localize --viz run.mcap`` (read back with the MCAP
library's own reader) and ``mfcl evaluate --plot fig.png``; bad output paths refused before
any work (exit 2, a message naming the path, nothing written)."""

from __future__ import annotations

import contextlib
import io
from types import SimpleNamespace

import numpy as np
import pytest
import shapely

from mfcl_jax.cli import main
from mfcl_jax.floorplan import save_geojson
from mfcl_jax.floorplan.load import load_floorplan
from mfcl_jax.io import read_decisions
from mfcl_jax.robot import status
from mfcl_jax.robot.viz import FRAME, TOPICS
from mfcl_jax.sim.scenes import symmetric_bays
from tests._mcap import _cloud, _no_leftovers, _read, _xyyaw

# The walk of tests/test_cli.py through the symmetric bays R1 -> R4: 11 windows of 6 m, the
# last ones COMMIT (what the layer decides before is its business: AMBIGUOUS windows are
# checked when there are some, and always in the writer's own test, test_viz_writer.py).
WAYPOINTS = [(1.0, 4.2), (3.0, 1.8), (27.0, 1.8)]


# ----------------------------------------------------------------------------- the CLI run
@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One simulated walk, localized once with ``--viz`` (the only localize run here)."""
    root = tmp_path_factory.mktemp("viz")
    plan = root / "bays.geojson"
    save_geojson(symmetric_bays().floorplan, plan)
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
