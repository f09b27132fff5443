"""3-D clouds through ``mfcl localize``: a simulated 3-D walk written as a dataset localizes
window by window as its 2-D twin does; the z-extent rule, the band flags, a tilted mount
levelled by ``--lidar-mount`` or ``/tf_static``; every bad input a one-line error naming the
file and value, nothing written, the inputs untouched."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mfcl_jax.cli import build_parser, main
from mfcl_jax.io import read_decisions, read_tum
from mfcl_jax.sim.lidar3d import cast3d, livox_mid360
from mfcl_jax.sim.scenes import symmetric_bays
from mfcl_jax.sim.world3d import build_geometry
from mfcl_jax.sources import write_dataset
from mfcl_jax.sources.cloud3d import BandParams
from mfcl_jax.sources.planar import PlanarParams, PlanarStream, input_dim, planar_scans
from mfcl_jax.sources.walk3d import walk3d

FP = symmetric_bays().floorplan
SENSOR = livox_mid360(n_azimuth=128, height=0.5)  # 5120 beams: a light Livox-like cloud
# R1 -> door line -> R2: 65 scans, 5 windows of 6 m.
WAYPOINTS = np.array([[1.0, 4.2], [3.0, 1.8], [16.0, 1.8]])


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    root = tmp_path_factory.mktemp("walk3d")
    w = walk3d(FP, WAYPOINTS, SENSOR, tag="bays3d")
    clouds = [c[np.all(np.isfinite(c), 1)] for c in w.clouds]
    d3 = write_dataset(root / "bays3d", FP, w.t, clouds, w.odom)
    d2 = write_dataset(root / "bays2d", FP, w.t, w.scans2d, w.odom)
    return root, d3, d2


def _snapshot(folder):
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _fails(argv, capsys, *words):
    """One ``mfcl: error:`` line naming ``words``, exit status 2."""
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mfcl: error:") and err.count("\n") == 1 and "Traceback" not in err
    for w in words:
        assert str(w) in err, err
    return err


def test_3d_dataset_localizes_as_its_2d_twin(walk, capsys):
    root, d3, d2 = walk
    # On the input odometry as it is: the band's scans are not the 2-D twin's point for point,
    # so scan matching would move the two runs' poses apart by millimetres.
    raw = ["--no-scan-match"]
    assert main(["localize", str(d3), "--out", str(root / "o3.jsonl"), *raw]) == 0
    err = capsys.readouterr().err
    assert "3-D clouds (median z extent" in err and "z in [0.90, 1.80] m above the floor" in err
    assert main(["localize", str(d2), "--out", str(root / "o2.jsonl"), *raw]) == 0
    assert "3-D clouds" not in capsys.readouterr().err
    a, b = read_decisions(root / "o3.jsonl"), read_decisions(root / "o2.jsonl")
    assert len(a) == len(b) == 5
    keys = ("k", "state", "symmetry", "B1", "B2", "margin", "reason")
    assert [[d[k] for k in keys] for d in a] == [[d[k] for k in keys] for d in b]
    for x, y in zip(a, b, strict=True):
        assert (x["tau"] is None) == (y["tau"] is None)
        if x["tau"] is not None:
            np.testing.assert_allclose(x["tau"], y["tau"], atol=0.05)


def test_z_extent_rule_and_input_dim(walk):
    _, d3, _ = walk
    flat = [np.c_[np.ones((5, 2)), np.full(5, z)] for z in (0.0, 0.1, 0.2)]
    assert input_dim(flat)[0] == 2 and input_dim([np.ones((4, 2))])[0] == 2
    tall = [np.c_[np.ones((5, 2)), np.linspace(0, 0.5, 5)]] * 3
    assert input_dim(tall) == (3, 0.5)
    scans, notes = planar_scans(tall, PlanarParams(dim=2), ["a"] * 3, "seq")
    assert (
        scans[0].shape == (5, 2) and "projected whole" in notes[0] and "--input-dim 2" in notes[0]
    )
    scans, notes = planar_scans(tall, PlanarParams(band=None), ["a"] * 3, "seq")
    assert "--no-band" in notes[0]
    # The CLI reads z only when a band will use it.
    from mfcl_jax.cli.inputs import dataset_folders, load_input

    args = build_parser().parse_args(["localize", str(d3), "--no-band"])
    _, seq, notes = load_input(args, dataset_folders(args))
    assert all(s.shape[1] == 2 for s in seq.scans) and "--no-band" in notes[-1]
    n_raw = len(seq.scans[10])
    args = build_parser().parse_args(["localize", str(d3), "--band-min", "0.5", "--band-max", "2"])
    _, seq, notes = load_input(args, dataset_folders(args))
    assert "z in [0.50, 2.00] m above the floor" in notes[-1] and len(seq.scans[10]) < n_raw


def test_band_errors_name_the_flag_or_scan(walk, tmp_path, capsys):
    root, d3, d2 = walk
    before = _snapshot(root)
    out = tmp_path / "o.jsonl"
    base = ["localize", d3, "--out", out]
    _fails(base + ["--band-min", "2", "--band-max", "1"], capsys,
           "--band-min < --band-max", "--band-min 2, --band-max 1")  # fmt: skip
    _fails(base + ["--band-min", "1.8"], capsys, "--band-min 1.8, --band-max 1.8")
    _fails(base + ["--no-band", "--band-max", "1"], capsys, "--no-band", "--band-max")
    first = d3 / "scans" / f"{read_tum(d3 / 'odometry.tum', with_strings=True)[2][0]}.pcd"
    _fails(base + ["--band-min", "5", "--band-max", "6"], capsys,
           first, "no point in the band z in [5.00, 6.00] m above the floor")  # fmt: skip
    # Planar scans told to be 3-D: no floor below the sensor anywhere.
    _fails(["localize", d2, "--input-dim", "3", "--out", out], capsys,
           d2, "no floor plane below the sensor in any of the 65 clouds")  # fmt: skip
    _fails(base + ["--lidar-mount", "0.3,0,0.5,0,2,0"], capsys,
           d3, "x, y, yaw must be 0 for a dataset", "0.3, 0, 0 deg")  # fmt: skip
    assert not out.exists() and _snapshot(root) == before
    with pytest.raises(SystemExit):
        main(["localize", str(d3), "--lidar-mount", "0,0,1"])
    assert "expected x,y,z,roll_deg,pitch_deg,yaw_deg" in capsys.readouterr().err


def _on_walls(points, pose) -> float:
    """Fraction of scan points (sensor frame, at plan pose ``pose``) within 5 cm of a wall."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    p = points @ np.array([[c, s], [-s, c]]) + pose[:2]
    segs = np.asarray(FP.wall_faces)
    a, e = segs[:, 0], segs[:, 1] - segs[:, 0]
    w = p[:, None] - a[None]
    u = np.clip(np.sum(w * e, -1) / np.sum(e * e, -1), 0, 1)
    return float(np.mean(np.min(np.linalg.norm(w - u[..., None] * e, axis=-1), axis=1) < 0.05))


POSES = np.array([[3.0, 2.0, 0.3], [10.0, 3.0, -1.2]])
TILT = dict(roll_deg=1.5, pitch_deg=8.0)  # pitched 8 deg down: the floor crosses the band
BAND = ["--band-relative-to", "sensor", "--band-min", "-0.3", "--band-max", "0.3"]


def _tilted_clouds():
    geom = build_geometry(FP.wall_faces, h_ceil=2.8)
    sensor = livox_mid360(n_azimuth=128, height=0.5, sigma=0.0, dropout=0.0, **TILT)
    clouds = np.asarray(cast3d(POSES, geom, sensor))
    return [c[np.all(np.isfinite(c), 1)] for c in clouds]


def test_lidar_mount_levels_a_tilted_dataset(tmp_path):
    from mfcl_jax.cli.inputs import dataset_folders, load_input

    ds = write_dataset(tmp_path / "tilted", FP, [0.0, 1.0], _tilted_clouds(), POSES)
    mount = f"0,0,0,{TILT['roll_deg']},{TILT['pitch_deg']},0"
    # Unlevelled, the sensor-frame band dips into the floor ahead and misses walls there.
    for extra, low, high, tilt in (([], 0.0, 0.95, 8.0), (["--lidar-mount", mount], 0.99, 1, 0)):
        args = build_parser().parse_args(["localize", str(ds), *BAND, *extra])
        _, seq, notes = load_input(args, dataset_folders(args))
        share = [_on_walls(s, p) for s, p in zip(seq.scans, POSES, strict=True)]
        assert low <= min(share) and max(share) <= high, (extra, share)
        assert f"tilt {tilt:.1f} deg" in notes[-1]


def test_tf_static_mount_levels_a_bag(tmp_path):
    from _bags import LIVOX, odometry, pointcloud2, store, tf_message, write_bag

    from mfcl_jax.cli.inputs import load_input

    r, p = math.radians(TILT["roll_deg"]), math.radians(TILT["pitch_deg"])
    # q = q_y(pitch) q_x(roll): the rotation Ry(pitch) Rx(roll) of the mount.
    q = (math.cos(p / 2) * math.sin(r / 2), math.sin(p / 2) * math.cos(r / 2),
         -math.sin(p / 2) * math.sin(r / 2), math.cos(p / 2) * math.cos(r / 2))  # fmt: skip
    ts = store()
    msgs = [("/tf_static", "tf2_msgs/msg/TFMessage", 0.0,
             tf_message(ts, [("base_link", "livox", (0.0, 0.0, 0.0), q)]))]  # fmt: skip
    for t in range(4):
        x, y, yaw = POSES[min(t, 1)]
        msgs.append(("/odom", "nav_msgs/msg/Odometry", t, odometry(ts, t, x, y, yaw)))
    for t, c in zip((1.0, 2.0), _tilted_clouds(), strict=True):
        msgs.append(("/points", "sensor_msgs/msg/PointCloud2", t,
                     pointcloud2(ts, t, c, LIVOX, frame="livox")))  # fmt: skip
    bag = write_bag(tmp_path / "b.bag", ts, msgs)
    plan = tmp_path / "p.geojson"
    from mfcl_jax.floorplan import save_geojson

    save_geojson(FP, plan)
    argv = ["localize", "--bag", str(bag), "--floorplan", str(plan), "--scan-topic", "/points"]
    for extra, low, high in (([], 0.0, 0.95), (["--tf-static"], 0.99, 1.0)):
        args = build_parser().parse_args(argv + BAND + extra)
        _, seq, notes = load_input(args)
        share = [_on_walls(s, p) for s, p in zip(seq.scans, POSES, strict=True)]
        assert low <= min(share) and max(share) <= high, (extra, share)
    assert "roll=1.50 deg, pitch=8.00 deg" in notes[0]


def test_planar_stream_waits_for_a_floor():
    clouds = _tilted_clouds()
    up = clouds[0][clouds[0][:, 2] > 0.0]  # no point below the sensor: no floor
    stream = PlanarStream(PlanarParams())
    assert stream.push(up, "up") == [] and stream.waiting == 1 and stream.dim == 3
    ready = stream.push(clouds[1], "c1")
    assert len(ready) == 2 and stream.waiting == 0
    whole, _ = planar_scans([up, clouds[1]], PlanarParams(), ["up", "c1"], "seq")
    for a, b in zip(ready, whole, strict=True):  # two clouds: the same median floor
        np.testing.assert_allclose(a, b)
    planar = PlanarStream(PlanarParams(band=BandParams()))
    assert planar.push(np.ones((3, 2)), "2d")[0].shape == (3, 2) and planar.dim == 2
