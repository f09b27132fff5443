"""The CLI's inputs: ROS-map thresholds and the unknown-grey warning, CARMEN logs, the LiDAR
mounting (``--lidar-offset``, ``--tf-static``), and a ``--help`` that imports nothing heavy."""

from __future__ import annotations

import math
import subprocess
import sys
import warnings
from importlib import import_module
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import box

from mfcl_jax.cli import main
from mfcl_jax.floorplan import Door, Floorplan, FloorplanWarning, Room, load_floorplan, save_geojson
from mfcl_jax.sources.data import data_dir

DATA = data_dir()
ROOT = Path(__file__).resolve().parents[1]


def _map(tmp_path, grey=206, share=0.3, free_thresh=0.196):
    from PIL import Image

    img = np.full((60, 80), 254, np.uint8)
    n = int(share * img.size)
    img.reshape(-1)[:n] = grey  # the unknown band at the top
    img[25, 5:75] = img[55, 5:75] = img[25:56, 5] = img[25:56, 75] = 0
    img[25:56, 40] = 0
    img[36:44, 40] = 254
    Image.fromarray(img).save(tmp_path / "m.png")
    (tmp_path / "m.yaml").write_text(
        "image: m.png\nresolution: 0.1\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        f"occupied_thresh: 0.65\nfree_thresh: {free_thresh}\n"
    )
    return tmp_path / "m.yaml"


def test_unknown_grey_read_as_free_warns(tmp_path):
    path = _map(tmp_path)
    with pytest.warns(FloorplanWarning) as rec:
        load_floorplan(path)
    msg = str(rec[0].message)
    assert "m.yaml" in msg and "grey level 206" in msg and "p = 0.1922" in msg
    assert "free_thresh=0.196" in msg and "--free-thresh 0.19" in msg
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_floorplan(path, free_thresh=0.19)  # read as unknown now: no warning
        load_floorplan(_map(tmp_path, grey=205))  # p = 0.196 is not under 0.196
        load_floorplan(_map(tmp_path, share=0.01))  # too few pixels to matter


def test_threshold_flags_reach_the_map(tmp_path, capsys):
    path = _map(tmp_path)
    out = tmp_path / "o.png"
    assert main(["floorplan", "show", str(path), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert err.startswith("mfcl: warning:") and "--free-thresh 0.19" in err
    argv = ["floorplan", "show", str(path), "--out", str(out), "--free-thresh", "0.19"]
    assert main(argv) == 0
    assert "warning" not in capsys.readouterr().err
    bad = ["floorplan", "show", str(path), "--free-thresh", "0.7", "--occupied-thresh", "0.6"]
    assert main(bad + ["--out", str(out)]) == 2
    assert "free_thresh=0.7, occupied_thresh=0.6" in capsys.readouterr().err
    plan = save_geojson(_plan(), tmp_path / "p.geojson")
    assert main(["floorplan", "show", str(plan), "--free-thresh", "0.2"]) == 2
    assert "free_thresh=0.2 applies to ROS maps (.yaml) only" in capsys.readouterr().err


@pytest.mark.skipif(not DATA.is_dir(), reason=f"real data folder {DATA} is absent")
def test_willow_through_the_cli(tmp_path, capsys):
    willow = DATA / "maps" / "willow-full.yaml"
    out = tmp_path / "w.png"
    assert main(["floorplan", "show", str(willow), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "50.6 % of the pixels have grey level 206" in err and "--free-thresh 0.19" in err
    assert main(["floorplan", "show", str(willow), "--out", str(out), "--free-thresh", "0.19"]) == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err
    assert int(captured.out.split(":")[1].split()[0]) >= 15  # rooms


def _plan() -> Floorplan:
    walls = np.array(
        [[[0, 0], [8, 0]], [[8, 0], [8, 4]], [[8, 4], [0, 4]], [[0, 4], [0, 0]]], float
    )
    return Floorplan(
        walls=walls,
        thickness=0.15,
        rooms=(Room("a", box(0, 0, 4, 4)), Room("b", box(4, 0, 8, 4))),
        doors=(Door(np.array([[4, 1.5], [4, 2.5]]), ("a", "b")),),
    )


class _Recorder:
    """Stands in for the JAX localizer and keeps the sequence it was given."""

    seen: list = []

    def __init__(self, fp, params=None):
        self.params = params

    def estimate(self, seq):
        _Recorder.seen.append(seq)
        return 0

    def run(self, seq):
        return iter(())


@pytest.fixture
def recorder(monkeypatch):
    _Recorder.seen = []
    monkeypatch.setattr(import_module("mfcl_jax.robot.localizer"), "Localizer", _Recorder)
    return _Recorder.seen


def _carmen(tmp_path):
    lines = ["# a CARMEN log", "PARAM robot_front_laser_max 50"]
    for i, t in enumerate([0.0, 0.5, 0.4, 1.0]):  # one time reversal
        r = " ".join(["2.0"] * 5)
        lines.append(f"FLASER 5 {r} {i} 0 0 {i} 0.1 {0.1 * i} {t} host {t}")
    p = tmp_path / "log.log"
    p.write_text("\n".join(lines) + "\n")
    return p


def test_carmen_log_with_lidar_offset(tmp_path, capsys, recorder):
    from mfcl_jax.io import read_carmen
    from mfcl_jax.io.tf_static import sensor_poses

    log_path = _carmen(tmp_path)
    plan = save_geojson(_plan(), tmp_path / "p.geojson")
    out = tmp_path / "d.jsonl"
    argv = ["localize", "--carmen", str(log_path), "--floorplan", str(plan), "--out", str(out)]
    assert main(argv + ["--lidar-offset", "0.3,-0.1,90"]) == 0
    err = capsys.readouterr().err
    assert "1 lines whose time goes backwards were left out" in err
    seq = recorder[-1]
    log = read_carmen(log_path)
    keep = [0, 1, 3]
    np.testing.assert_allclose(seq.times, log.times[keep])
    expect = sensor_poses(log.odometry[keep], (0.3, -0.1, math.pi / 2))
    np.testing.assert_allclose(seq.odometry, expect, atol=1e-12)
    assert out.read_text() == ""  # no windows: an empty, valid log
    assert main(argv[:-2] + ["--out", str(out)]) == 0
    np.testing.assert_allclose(recorder[-1].odometry, log.odometry[keep])


def _fails(argv, capsys, *words):
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mfcl: error:") and "Traceback" not in err
    for w in words:
        assert w in err, err


def test_input_flag_errors(tmp_path, capsys, recorder):
    from mfcl_jax.sources import write_dataset

    ds = write_dataset(
        tmp_path / "ds", _plan(), [0.0, 1.0], [np.ones((3, 2))] * 2, np.zeros((2, 3))
    )
    log = _carmen(tmp_path)
    out = tmp_path / "d.jsonl"
    _fails(["localize", ds, "--lidar-offset", "1,2,3", "--out", out], capsys, "already the sensor")
    _fails(["localize", ds, "--tf-static", "--out", out], capsys, "--tf-static", "give --bag")
    _fails(["localize", ds, "--carmen", log, "--out", out], capsys, "DATASET and --carmen")
    _fails(["localize", "--carmen", log, "--out", out], capsys, "log.log", "--floorplan")
    plan = save_geojson(_plan(), tmp_path / "p.geojson")
    _fails(["localize", ds, "--floorplan", plan, "--free-thresh", "0.19", "--out", out], capsys,
           "p.geojson: free_thresh=0.19 applies to ROS maps (.yaml) only")  # fmt: skip
    with pytest.raises(SystemExit) as e:
        main(["localize", str(ds), "--lidar-offset", "1,2"])
    assert e.value.code == 2
    assert "--lidar-offset: expected x,y,yaw_deg" in capsys.readouterr().err
    assert not out.exists() and recorder == []


def test_tf_static_through_the_cli(tmp_path, capsys, recorder):
    from _bags import OUSTER, odometry, pointcloud2, quat_yaw, store, tf_message, write_bag

    ts = store()
    mount = tf_message(ts, [("base_link", "os_sensor", (0.5, 0.0, 1.0), quat_yaw(0.0))])
    msgs = [("/tf_static", "tf2_msgs/msg/TFMessage", 0.0, mount)]
    msgs += [("/odom", "nav_msgs/msg/Odometry", t, odometry(ts, t, t, 0.0, 0.0)) for t in range(5)]
    xyz = np.random.default_rng(0).uniform(-5, 5, (10, 3))
    msgs += [("/points", "sensor_msgs/msg/PointCloud2", t, pointcloud2(ts, t, xyz, OUSTER,
              frame="os_sensor")) for t in (1.0, 2.0)]  # fmt: skip
    bag = write_bag(tmp_path / "b.bag", ts, msgs)
    plan = save_geojson(_plan(), tmp_path / "p.geojson")
    out = tmp_path / "d.jsonl"
    argv = ["localize", "--bag", bag, "--floorplan", plan, "--scan-topic", "/points", "--out", out]
    argv += ["--no-band"]  # ten random points: no floor to cut a band above
    assert main([str(a) for a in argv + ["--tf-static"]]) == 0
    assert "base_link -> os_sensor: x=0.500 m, y=0.000 m, yaw=0.00 deg" in capsys.readouterr().err
    np.testing.assert_allclose(recorder[-1].odometry, [[1.5, 0, 0], [2.5, 0, 0]])
    out.unlink()
    _fails(argv + ["--tf-static", "--base-frame", "chassis"], capsys, "b.bag /tf_static",
           "'chassis' to 'os_sensor'", "frames present: base_link, os_sensor")  # fmt: skip
    assert not out.exists()


def test_help_imports_nothing_heavy():
    heavy = ("jax", "matplotlib", "scipy", "pandas", "rosbags", "ifcopenshell", "shapely")
    code = (
        "import sys\n"
        "import mfcl_jax.cli\n"
        f"after_import = [m for m in {heavy!r} if m in sys.modules]\n"
        "try:\n"
        "    mfcl_jax.cli.main(['--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        f"after_help = [m for m in {heavy!r} if m in sys.modules]\n"
        "print(after_import, after_help)\n"
    )
    env_path = str(ROOT)
    res = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env={"PYTHONPATH": env_path, "PATH": "/usr/bin:/bin"},
        check=True,
    )
    assert res.stdout.strip().splitlines()[-1] == "[] []", res.stdout
