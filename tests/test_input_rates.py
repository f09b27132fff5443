"""Issue 29, item 1: odometry at any rate matched to scans by time (SE(2) interpolation,
dataset folders; units and frames: test_input_units.py; bags: test_input_bags.py).

Each test fails on the code before the issue: stamps were matched as strings, one odometry
line per scan.
"""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

from mfcl_jax.io import DataError, read_tum, write_tum
from mfcl_jax.io.errors import DataWarning
from mfcl_jax.io.timesync import TIME_TOL_S, interpolate_se2, odometry_at
from mfcl_jax.sources import from_dataset, load_dataset, write_dataset
from tests._inputs import T0, _dataset, _plan, _quiet, _scan_times, _scans, _truth, _yaw_err

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
