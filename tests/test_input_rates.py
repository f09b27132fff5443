"""Issue 29, items 1 and 2: odometry at any rate matched to scans by time, and units and
frames checked (non-unit quaternions, millimetre scans, plan and scans of different scales).

Each test fails on the code before the issue: stamps were matched as strings, one odometry
line per scan; quaternions were read as if unit; scans were never checked for units.
"""

from __future__ import annotations

import math
import re
import shutil
import warnings

import numpy as np
import pytest
from _bags import VELODYNE, odometry, pointcloud2, quat_yaw, store, tf_message, write_bag
from shapely.geometry import box

from mfcl_jax.floorplan import Door, Floorplan, Room
from mfcl_jax.io import DataError, read_bag, read_carmen, read_tum, write_tum
from mfcl_jax.io.errors import DataWarning
from mfcl_jax.io.timesync import TIME_TOL_S, interpolate_se2, odometry_at
from mfcl_jax.io.tum import yaw_from_quat
from mfcl_jax.sources import from_carmen, from_dataset, load_dataset, write_dataset

T0 = 1000.0
TS1 = store(ros1=True)
PC2 = "sensor_msgs/msg/PointCloud2"
ODOM = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"


def _plan(k: float = 1.0) -> Floorplan:
    walls = k * np.array(
        [[[0, 0], [8, 0]], [[8, 0], [8, 4]], [[8, 4], [0, 4]], [[0, 4], [0, 0]],
         [[4, 0], [4, 1.5]], [[4, 2.5], [4, 4]]], float,
    )  # fmt: skip
    return Floorplan(
        walls=walls,
        thickness=0.15 * k,
        rooms=(Room("a", box(0, 0, 4 * k, 4 * k)), Room("b", box(4 * k, 0, 8 * k, 4 * k))),
        doors=(Door(k * np.array([[4, 1.5], [4, 2.5]]), ("a", "b")),),
        name=f"plan x{k:g}",
    )


def _truth(t) -> np.ndarray:
    """A constant-velocity path (so linear interpolation is exact) whose heading crosses pi."""
    dt = np.asarray(t, np.float64) - T0
    yaw = np.arctan2(np.sin(2.9 + 0.5 * dt), np.cos(2.9 + 0.5 * dt))
    return np.stack([1.0 + 0.3 * dt, 2.0 + 0.1 * dt, yaw], -1)


def _scans(n, seed=0, k=1.0):
    rng = np.random.default_rng(seed)
    return [k * rng.normal(size=(30, 2)) for _ in range(n)]


def _scan_times(n=20):
    # 10 Hz, between the 100 Hz odometry stamps (3.7 ms after each tick).
    return T0 + 0.1 * np.arange(n) + 0.0037


def _dataset(tmp_path, name="ref", times=None, **kw):
    times = _scan_times() if times is None else times
    plan = kw.pop("plan", _plan())
    scans = kw.pop("scans", _scans(len(times)))
    return write_dataset(tmp_path / name, plan, times, scans, _truth(times), **kw)


def _yaw_err(a, b) -> float:
    return float(np.max(np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))))


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return fn(*a, **kw)


# ---------------------------------------------------------------- SE(2) interpolation


def test_interpolate_se2_exact_at_stamps_linear_between_shortest_heading():
    t = np.array([0.0, 1.0, 3.0])
    poses = np.array([[0.0, 0.0, 3.0], [2.0, 4.0, -3.0], [6.0, 4.0, -2.0]])
    out = interpolate_se2(t, poses, [0.0, 0.5, 1.0, 2.0, 3.0])
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out[[0, 2, 4], :2], poses[:, :2])
    np.testing.assert_allclose(out[1, :2], [1.0, 2.0])
    np.testing.assert_allclose(out[3, :2], [4.0, 4.0])
    # 3.0 -> -3.0 rad is 0.28 rad through pi, not 6 rad through 0: the midpoint is pi.
    assert _yaw_err(out[1, 2], math.pi) < 1e-12
    assert _yaw_err(out[3, 2], -2.5) < 1e-12 and _yaw_err(out[[0, 2, 4], 2], poses[:, 2]) < 1e-12


def test_odometry_at_tolerance_and_span():
    t = np.array([10.0, 11.0])
    poses = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    edge = [10.0 - 0.5 * TIME_TOL_S, 11.0 + 0.5 * TIME_TOL_S]
    inside, out = _quiet(odometry_at, t, poses, edge, "o.tum")
    assert inside.all()
    np.testing.assert_array_equal(out[:, 0], [0.0, 1.0])  # the end poses, not extrapolated
    with pytest.warns(DataWarning, match=r"o\.tum: 1 of 2 scans lie outside"):
        inside, _ = odometry_at(t, poses, [10.5, 11.0 + 2 * TIME_TOL_S], "o.tum")
    assert inside.tolist() == [True, False]


# ---------------------------------------------------------------- dataset folders


def test_100hz_odometry_loads_like_one_line_per_scan(tmp_path):
    ref = _dataset(tmp_path)
    fast = tmp_path / "fast"
    shutil.copytree(ref, fast)
    t100 = T0 - 0.05 + 0.01 * np.arange(211)  # 100 Hz, past both ends of the scans
    write_tum(fast / "odometry.tum", t100, _truth(t100), [f"{t:.6f}" for t in t100])
    assert (fast / "scans" / "1000.1037.pcd").is_file()  # scans named unlike the odometry
    a = from_dataset(_quiet(load_dataset, ref))
    b = from_dataset(_quiet(load_dataset, fast))
    np.testing.assert_array_equal(a.times, b.times)
    np.testing.assert_allclose(b.odometry[:, :2], a.odometry[:, :2], atol=1e-6)
    assert _yaw_err(b.odometry[:, 2], a.odometry[:, 2]) < 1e-6
    assert np.ptp(np.unwrap(a.odometry[:, 2])) > 0.5  # the heading did cross pi
    for x, y in zip(a.scans, b.scans, strict=True):
        np.testing.assert_array_equal(x, y)


def test_stamps_written_differently_match(tmp_path):
    out = _dataset(tmp_path, times=T0 + np.array([0.0, 0.5, 1.0]))
    t, poses, _ = read_tum(out / "odometry.tum", with_strings=True)
    write_tum(out / "odometry.tum", t, poses, ["1000.000000", "1000.500000", "1.001e3"])
    ds = _quiet(load_dataset, out)
    assert ds.time_strings == ("1000", "1000.5", "1001")
    np.testing.assert_allclose(ds.odometry[:, :2], poses[:, :2], atol=1e-12)


def test_groundtruth_at_its_own_rate(tmp_path):
    out = _dataset(tmp_path)
    t50 = T0 + 0.02 * np.arange(101)
    write_tum(out / "groundtruth.tum", t50, _truth(t50) + [5.0, 0.0, 0.0])
    ds = _quiet(load_dataset, out)
    np.testing.assert_allclose(ds.groundtruth[:, 0], _truth(ds.times)[:, 0] + 5.0, atol=1e-9)
    write_tum(out / "groundtruth.tum", t50[:50], _truth(t50[:50]))
    with pytest.raises(DataError, match=r"groundtruth\.tum: 10 of 20 scans lie outside"):
        load_dataset(out)


def test_scans_outside_the_odometry_span_are_skipped_with_a_warning(tmp_path):
    out = _dataset(tmp_path)
    t = T0 + 0.3 + 0.01 * np.arange(101)  # covers [1000.3, 1001.3]: scans 3..12 of 20
    t = np.append(t, _scan_times()[13] - 0.5 * TIME_TOL_S)  # scan 13 is within 1 ms of it
    write_tum(out / "odometry.tum", t, _truth(t))
    with pytest.warns(DataWarning) as rec:
        ds = load_dataset(out)
    msg = str(rec[0].message)
    assert str(out / "odometry.tum") in msg and "9 of 20 scans lie outside" in msg
    assert "[1000.300000, 1001.303200] s" in msg and "tolerance 1 ms" in msg
    assert len(ds) == 11 and ds.outside == 9
    np.testing.assert_allclose(ds.times, _scan_times()[3:14], atol=1e-9)


def test_every_scan_outside_is_an_error(tmp_path):
    out = _dataset(tmp_path)
    t = T0 + 10 + 0.01 * np.arange(50)
    write_tum(out / "odometry.tum", t, _truth(t))
    with pytest.raises(DataError) as e:
        load_dataset(out)
    msg = str(e.value)
    assert "odometry.tum: no scan lies within the odometry's time span" in msg
    assert "[1010.000000, 1010.490000] s" in msg and "20 scans span [1000.003700" in msg


@pytest.mark.parametrize(
    "stamps, words",
    [
        (["1000", "1000.5", "1000.500", "1001"], ["odometry.tum:4: timestamp 1000.500", "repeats"]),
        (
            ["1000", "1000.5", "1000.2", "1001"],
            ["odometry.tum:4: timestamp 1000.2", "back in time"],
        ),
    ],
)
def test_odometry_duplicate_or_backwards_stamps(tmp_path, stamps, words):
    out = _dataset(tmp_path, times=T0 + np.array([0.0, 1.0]))
    body = "".join(f"{s} 0 0 0 0 0 0 1\n" for s in stamps)
    (out / "odometry.tum").write_text("# t x y z qx qy qz qw\n" + body)
    with pytest.raises(DataError) as e:
        load_dataset(out)
    for w in words + ["previous 1000.5 at line 3", "strictly increasing"]:
        assert w in str(e.value)


def test_two_scan_files_at_one_time(tmp_path):
    out = _dataset(tmp_path, times=T0 + np.array([0.0, 0.5, 1.0]))
    shutil.copy(out / "scans" / "1000.5.pcd", out / "scans" / "1000.50.pcd")
    with pytest.raises(DataError, match=r"scan time t=1000\.5 is also the time of 1000\.5"):
        load_dataset(out)


# ---------------------------------------------------------------- quaternions


def _tum_lines(yaw_deg, scale):
    q = scale * np.array(
        [0, 0, math.sin(math.radians(yaw_deg) / 2), math.cos(math.radians(yaw_deg) / 2)]
    )
    return [f"{T0 + i} {i} 0 0 {q[0]:.9g} {q[1]:.9g} {q[2]:.9g} {q[3]:.9g}" for i in range(3)]


def test_quaternion_scaled_by_2_warns_and_gives_the_right_yaw(tmp_path):
    path = tmp_path / "o.tum"
    path.write_text("\n".join(["# t x y z qx qy qz qw"] + _tum_lines(84.0, 2.0)) + "\n")
    with pytest.warns(DataWarning) as rec:
        _, poses = read_tum(path)
    np.testing.assert_allclose(np.degrees(poses[:, 2]), 84.0, atol=1e-6)  # not 123 deg
    msg = str(rec[0].message)
    assert f"{path}:2: quaternion norm 2 differs from 1" in msg and "3 of 3" in msg
    assert "normalised" in msg and len(rec) == 1
    assert abs(math.degrees(yaw_from_quat([0, 0, 2 * 0.669130606, 2 * 0.743144825])) - 84) < 1e-6


def test_quaternion_within_tolerance_is_quiet(tmp_path):
    path = tmp_path / "o.tum"
    path.write_text("\n".join(_tum_lines(30.0, 1.0005)) + "\n")
    _, poses = _quiet(read_tum, path)
    np.testing.assert_allclose(np.degrees(poses[:, 2]), 30.0, atol=1e-6)


@pytest.mark.parametrize("scale", [0.0, 1e-8])
def test_degenerate_quaternion_refused(tmp_path, scale):
    path = tmp_path / "o.tum"
    lines = _tum_lines(30.0, 1.0)
    lines[1] = " ".join(lines[1].split()[:4] + [f"{scale * v:.9g}" for v in (0, 0, 0.5, 0.8)])
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"o\.tum:2: degenerate quaternion .* norm"):
        read_tum(path)


# ---------------------------------------------------------------- units


def test_millimetre_scans_refused_naming_file_and_median(tmp_path):
    out = _dataset(tmp_path, scans=_scans(20, k=1000.0), plan=_plan())
    with pytest.raises(DataError) as e:
        load_dataset(out)
    msg = str(e.value)
    assert str(out / "scans" / "1000.0037.pcd") in msg and "millimetres" in msg
    assert re.search(r"median range \d{4} over the first 20 scans", msg)
    assert "expects scans in metres" in msg


def test_plan_and_scans_of_different_scales_refused(tmp_path):
    out = _dataset(tmp_path)
    with pytest.raises(DataError) as e:
        load_dataset(out, floorplan=_plan(1000.0))
    msg = str(e.value)
    assert "plan x1000" in msg and "disagree in scale" in msg and "8150 x 4150 units" in msg
    assert str(out / "scans") in msg and "both in metres" in msg
    assert len(_quiet(load_dataset, out, floorplan=_plan(3.0))) == 20  # a larger building


def _flaser(t, readings, x=0.0):
    r = " ".join(f"{v:g}" for v in readings)
    return f"FLASER {len(readings)} {r} {x} 0 0 {x} 0 0 {t} host {t}\n"


def test_carmen_millimetres_refused_and_odometry_through_timesync(tmp_path):
    good = tmp_path / "g.log"
    good.write_text("".join(_flaser(1.0 + i, [2.0, 3.0, 4.0], x=i) for i in range(4)))
    log = _quiet(read_carmen, good)
    seq = from_carmen(log)
    np.testing.assert_array_equal(seq.odometry[:, 0], [0, 1, 2, 3])
    with pytest.raises(DataError, match=r"g\.log: 3 odometry poses for 4 FLASER lines"):
        from_carmen(log, odometry=np.zeros((3, 3)), source=str(good))
    mm = tmp_path / "mm.log"
    mm.write_text("".join(_flaser(1.0 + i, [2000.0, 3000.0, 4000.0]) for i in range(4)))
    with pytest.raises(DataError) as e:
        read_carmen(mm)
    assert f"{mm}:1: scan ranges look like millimetres" in str(e.value)
    assert "median range 3000" in str(e.value)


# ---------------------------------------------------------------- bags


def _cloud(t, k=1.0):
    xyz = np.random.default_rng(int(t * 10)).uniform(-8, 8, size=(16, 3)).astype(np.float32)
    return pointcloud2(TS1, t, k * xyz, VELODYNE)


def _bag(tmp_path, odom_msgs, k=1.0, name="r.bag"):
    scans = [("/points", PC2, t, _cloud(t, k)) for t in _scan_times(10)]
    return write_bag(tmp_path / name, TS1, odom_msgs + scans)


def _odom_msgs(times, q_scale=1.0):
    return [
        ("/odom", ODOM, t, odometry(TS1, t, *map(float, _truth(t)), q_scale=q_scale)) for t in times
    ]


def test_bag_odom_at_100hz_interpolated_and_outside_scans_warned(tmp_path):
    t100 = T0 + 0.2 + 0.01 * np.arange(81)  # scans 2..9 of 10 inside
    path = _bag(tmp_path, _odom_msgs(t100))
    with pytest.warns(DataWarning, match=r"r\.bag /odom: 2 of 10 scans lie outside"):
        bag = read_bag(path, scan_topic="/points")
    assert len(bag) == 8 and bag.unpaired == 2
    np.testing.assert_allclose(bag.odometry[:, :2], _truth(bag.times)[:, :2], atol=1e-6)
    assert _yaw_err(bag.odometry[:, 2], _truth(bag.times)[:, 2]) < 1e-6


def test_bag_odometry_quaternions_scaled_by_2(tmp_path):
    t100 = T0 + 0.01 * np.arange(101)
    path = _bag(tmp_path, _odom_msgs(t100, q_scale=2.0))
    with pytest.warns(DataWarning, match=r"r\.bag /odom t=1000\.0+: quaternion norm 2 differs"):
        bag = read_bag(path, scan_topic="/points")
    assert _yaw_err(bag.odometry[:, 2], _truth(bag.times)[:, 2]) < 1e-6
    zero = _bag(tmp_path, _odom_msgs(t100, q_scale=0.0), name="z.bag")
    with pytest.raises(DataError, match=r"z\.bag /odom t=1000\.0+: degenerate quaternion"):
        read_bag(zero, scan_topic="/points")


def test_bag_odometry_from_tf(tmp_path):
    t100 = T0 + 0.01 * np.arange(101)
    tfs = [
        ("/tf", TF, t, tf_message(TS1, [("odom", "base_link", (*_truth(t)[:2], 0.0),
                                         quat_yaw(_truth(t)[2]))], t=t))
        for t in t100
    ]  # fmt: skip
    path = _bag(tmp_path, tfs)
    bag = _quiet(read_bag, path, scan_topic="/points", odom_topic="/tf")
    np.testing.assert_allclose(bag.odometry[:, :2], _truth(bag.times)[:, :2], atol=1e-6)
    assert _yaw_err(bag.odometry[:, 2], _truth(bag.times)[:, 2]) < 1e-6
    with pytest.raises(DataError, match=r"no transform map -> base_link; .* odom -> base_link"):
        read_bag(path, scan_topic="/points", odom_topic="/tf", odom_frames=("map", "base_link"))


def test_bag_millimetre_scans_refused(tmp_path):
    path = _bag(tmp_path, _odom_msgs(T0 + 0.01 * np.arange(101)), k=1000.0)
    with pytest.raises(DataError) as e:
        read_bag(path, scan_topic="/points")
    assert "r.bag /points scan at t=1000.003700000" in str(e.value)
    assert "millimetres" in str(e.value) and "expects scans in metres" in str(e.value)


def test_a_dataset_written_with_100hz_odometry_loads_like_one_pose_per_scan(tmp_path):
    """``write_dataset(odom_times=...)`` (``mfcl simulate --odom-rate``) writes the odometry
    at its own rate and stamps; the loader interpolates it back at the scans' stamps."""
    times = _scan_times()
    ref = _dataset(tmp_path)
    t100 = T0 + 0.01 * np.arange(196)  # 100 Hz, from before the first scan to past the last
    fast = write_dataset(tmp_path / "fast", _plan(), times, _scans(len(times)), _truth(t100),
                         odom_times=t100)  # fmt: skip
    lines = (fast / "odometry.tum").read_text().splitlines()
    assert len([ln for ln in lines if not ln.startswith("#")]) == 196
    a = from_dataset(_quiet(load_dataset, ref))
    b = from_dataset(_quiet(load_dataset, fast))
    np.testing.assert_allclose(b.odometry[:, :2], a.odometry[:, :2], atol=1e-6)
    assert _yaw_err(b.odometry[:, 2], a.odometry[:, 2]) < 1e-6
    with pytest.raises(DataError, match="196 odometry times and 20 odometry poses"):
        write_dataset(tmp_path / "bad", _plan(), times, _scans(len(times)), _truth(times),
                      odom_times=t100)  # fmt: skip
    assert not (tmp_path / "bad").exists()


def test_a_carmen_log_against_a_plan_of_another_scale_is_refused(tmp_path, capsys):
    """``mfcl localize --carmen`` checks the plan's scale against the scans' as a dataset
    folder does (here a plan far smaller than what the scans see)."""
    from mfcl_jax.cli import main
    from mfcl_jax.floorplan.geojson import save_geojson

    log = tmp_path / "g.log"
    log.write_text("".join(_flaser(1.0 + i, [2.0, 3.0, 4.0] * 60, x=0.1 * i) for i in range(6)))
    plan = save_geojson(_plan(0.01), tmp_path / "plan_small.geojson")  # 8 cm: scans see past it
    out = tmp_path / "d.jsonl"
    rc = main(["localize", "--carmen", str(log), "--floorplan", str(plan), "--out", str(out),
               "--quiet"])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "disagree in scale" in err and str(plan) in err, err
    assert not out.exists()
