"""Simulator: ray casting against analytic cases, windows, frames, determinism, contracts."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest

from mfcl_jax import se2
from mfcl_jax import windows as W
from mfcl_jax.sim import LidarParams, SimParams, TrajectoryParams, cast, sample_path
from mfcl_jax.sim import raycast as rc
from mfcl_jax.sim.scenes import symmetric_bays
from mfcl_jax.sources.simulated import simulate
from mfcl_jax.windows import ScanMatchParams, window_bounds
from mfcl_jax.windows.arrays import RunBatch, SubmapBatch

EXACT = LidarParams(n_beams=360, sigma=0.0, dropout=0.0)
CLEAN = SimParams(lidar=EXACT, trajectory=TrajectoryParams(drift_xy=0.0, drift_yaw_deg_per_m=0.0))


def _circle(radius, n=720, centre=(0.0, 0.0)):
    a = np.linspace(0, 2 * np.pi, n + 1)
    p = np.stack([radius * np.cos(a), radius * np.sin(a)], 1) + centre
    return np.stack([p[:-1], p[1:]], 1)


def _corridor(half_len=10.0, half_w=1.0):
    L, W = half_len, half_w
    return np.array(
        [[[-L, -W], [L, -W]], [[-L, W], [L, W]], [[-L, -W], [-L, W]], [[L, -W], [L, W]]], float
    )


def _apply(pose, p):
    """NumPy twin of se2.apply for one pose (keeps the loops below free of JAX dispatch)."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return p @ np.array([[c, s], [-s, c]]) + pose[:2]


def _dist_to_segments(p, segs):
    a, b = segs[:, 0], segs[:, 1]
    ab = b - a
    t = np.clip(np.einsum("nmk,mk->nm", p[:, None] - a[None], ab) / np.sum(ab * ab, 1), 0, 1)
    q = a[None] + t[..., None] * ab[None]
    return np.min(np.linalg.norm(p[:, None] - q, axis=-1), axis=1)


# ---------------------------------------------------------------------------- ray casting
def test_circle_all_ranges_equal_radius():
    rng = np.random.default_rng(0)
    centre = np.array([2.0, -1.0])
    poses = np.concatenate([np.tile(centre, (5, 1)), rng.uniform(-3, 3, (5, 1))], 1)
    r = np.asarray(cast(poses, _circle(5.0, centre=centre), EXACT))
    assert r.shape == (5, 360)
    np.testing.assert_allclose(r, 5.0, atol=1e-3)


def test_corridor_perpendicular_and_axial_ranges():
    params = dataclasses.replace(EXACT, n_beams=8)
    poses = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, np.pi / 2], [4.0, 0.5, 0.0]])
    r = np.asarray(cast(poses, _corridor(), params))
    # Beams every 45 deg from the heading.
    np.testing.assert_allclose(r[0, [0, 2, 4, 6]], [10.0, 1.0, 10.0, 1.0], atol=1e-4)
    np.testing.assert_allclose(r[0, 1], np.sqrt(2.0), atol=1e-4)
    np.testing.assert_allclose(r[1, [0, 2, 4, 6]], [1.0, 10.0, 1.0, 10.0], atol=1e-4)
    np.testing.assert_allclose(r[2, [0, 2, 4, 6]], [6.0, 0.5, 14.0, 1.5], atol=1e-4)


def test_misses_are_invalid_not_max_range():
    params = dataclasses.replace(EXACT, n_beams=8, max_range=40.0)
    segs = np.array([[[3.0, -1.0], [3.0, 1.0]], [[-50.0, -1.0], [-50.0, 1.0]]])
    r = np.asarray(cast(np.zeros((1, 3)), segs, params))[0]
    assert r[0] == pytest.approx(3.0, abs=1e-5)
    assert np.all(np.isnan(r[1:])), r  # beam 4 hits at 50 m > max_range: also invalid
    # min range: a wall 5 cm away is not seen.
    near = np.array([[[0.05, -1.0], [0.05, 1.0]]])
    assert np.isnan(np.asarray(cast(np.zeros((1, 3)), near, params))[0, 0])


def test_padded_segments_are_ignored():
    segs = _corridor()
    pad = np.concatenate([segs, np.zeros((4, 2, 2)), [[[5.0, -1.0], [5.0, 1.0]]]])
    valid = np.r_[np.ones(4, bool), np.zeros(5, bool)]
    params = dataclasses.replace(EXACT, n_beams=8)
    r = np.asarray(cast(np.zeros((1, 3)), pad, params, seg_valid=valid))
    assert r[0, 0] == pytest.approx(10.0, abs=1e-4)


def test_dropout_rate_and_noise_statistics():
    params = LidarParams(n_beams=720, sigma=0.02, dropout=0.1)
    poses = np.zeros((20, 3))
    r = np.asarray(cast(poses, _circle(8.0), params, key=jax.random.PRNGKey(3)))
    n = r.size
    rate = np.mean(np.isnan(r))
    assert abs(rate - 0.1) < 4 * np.sqrt(0.1 * 0.9 / n), rate
    err = r[~np.isnan(r)] - 8.0
    assert abs(np.mean(err)) < 0.002 and 0.018 < np.std(err) < 0.022


def test_cast_is_deterministic_and_jit_free_kernel_agrees():
    segs = _corridor()
    poses = np.array([[1.0, 0.2, 0.3], [-2.0, -0.4, 2.0]])
    p = LidarParams(n_beams=16)
    a = np.asarray(cast(poses, segs, p, key=jax.random.PRNGKey(7)))
    b = np.asarray(cast(poses, segs, p, key=jax.random.PRNGKey(7)))
    c = np.asarray(cast(poses, segs, p, key=jax.random.PRNGKey(8)))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(np.nan_to_num(a), np.nan_to_num(c))
    keys = jax.random.split(jax.random.PRNGKey(7), 2)
    d = np.asarray(
        rc.cast_kernel(
            poses, segs, np.ones(4, bool), keys, 16, p.min_range, p.max_range, p.sigma, p.dropout
        )
    )
    np.testing.assert_allclose(a, d, atol=1e-5)


def test_bad_inputs_named():
    with pytest.raises(ValueError, match="dropout"):
        LidarParams(dropout=1.5)
    with pytest.raises(ValueError, match="segments must be"):
        cast(np.zeros((1, 3)), np.zeros((3, 4)))
    with pytest.raises(ValueError, match="NaN"):
        cast(np.full((1, 3), np.nan), _corridor())


# ---------------------------------------------------------------------------- trajectories
def test_sample_path_spacing_heading_and_times():
    path = sample_path(np.array([[0.0, 0.0], [20.0, 0.0]]), TrajectoryParams(speed=0.5))
    assert len(path.poses) == 81
    np.testing.assert_allclose(np.diff(path.poses[:, 0]), 0.25, atol=1e-9)
    np.testing.assert_allclose(path.poses[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(path.t[-1], 40.0)
    corner = sample_path(np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]]))
    dth = np.abs(np.diff(corner.poses[:, 2]))
    assert dth.max() < np.deg2rad(30), "heading must turn gradually at a corner"
    np.testing.assert_allclose(corner.poses[-1, 2], np.pi / 2, atol=1e-6)


def test_window_counts_on_straight_path():
    s = np.arange(81) * 0.25  # 20 m straight
    w = window_bounds(s, 6.0, 2.0)
    # floor((20 - 6) / 2) + 1 = 8 windows: starts at 0, 2, ..., 14 m, each 6 m long.
    assert len(w) == 8
    np.testing.assert_array_equal(w[:, 0], np.arange(8) * 8)
    np.testing.assert_array_equal(w[:, 1] - w[:, 0], 24)
    assert len(window_bounds(s, 5.0, 2.0)) == 8 and len(window_bounds(s, 7.0, 2.0)) == 7
    assert len(window_bounds(s, 21.0, 2.0)) == 0


# ---------------------------------------------------------------------------- simulate
@pytest.fixture(scope="module")
def bays():
    return symmetric_bays()


def _windows(recs, d_s=6.0):
    """Recordings cut and packed the way every consumer does it, on the simulated odometry as
    it is (no LiDAR odometry: these tests check the simulator's frames and drift)."""
    wp = W.WindowParams(d_s=d_s, scan_match=ScanMatchParams(enabled=False))
    wins = [W.cut(r.seq, wp) for r in recs]
    return W.pack([(r.seq, w, 0) for r, w in zip(recs, wins, strict=True)]), wins


def _true_at(rec, w):
    """True sensor pose of every window's last scan."""
    return rec.truth.poses[w.last_scan()]


@pytest.fixture(scope="module")
def clean_sim(bays):
    recs = simulate(bays, ["S1"], [0], CLEAN)
    wb, wins = _windows(recs)
    return recs, wb, wins


def test_contracts_and_windows(clean_sim):
    recs, wb, wins = clean_sim
    sm, rb = wb.submaps, wb.runs
    assert isinstance(sm, SubmapBatch) and isinstance(rb, RunBatch)
    assert recs[0].meta["trajectory"] == "S1" and recs[0].truth is not None
    n = sm.n
    assert n == int(rb.window_mask.sum()) == len(wins[0]) == 12
    assert sm.points.shape[1] % 256 == 0 and sm.points.shape == sm.origins.shape
    for i in range(n):
        r, w = int(sm.run[i]), int(sm.window[i])
        assert int(rb.submap[r, w]) == i
        j = int(rb.window_end[r, w])
        np.testing.assert_allclose(np.asarray(sm.X[i]), np.asarray(rb.traj[r, j]), atol=1e-6)
    assert int(np.asarray(sm.n_dropped).sum()) == 0
    assert np.all(np.asarray(sm.mask).sum(1) > 300)


def test_frames_zero_drift_map_to_the_same_world(clean_sim, bays):
    recs, wb, wins = clean_sim
    sm, rb = wb.submaps, wb.runs
    Y = _true_at(recs[0], wins[0])
    np.testing.assert_allclose(np.asarray(rb.traj[0, 0]), 0.0, atol=1e-6)  # L = start pose
    # Every submap's anchor Y X^-1 is the hidden anchor (the true start pose).
    H = np.asarray(se2.anchor(Y, np.asarray(sm.X, np.float64)))
    start = recs[0].truth.poses[0]
    np.testing.assert_allclose(H[:, :2], np.broadcast_to(start[:2], (sm.n, 2)), atol=1e-3)
    segs = bays.segments
    world = []
    for i in range(sm.n):
        m = np.asarray(sm.mask[i])
        p = _apply(Y[i], np.asarray(sm.points[i], np.float64)[m])
        assert np.max(_dist_to_segments(p, segs)) < 2e-3  # every point lies on a surface
        o = _apply(Y[i], np.asarray(sm.origins[i], np.float64)[m][::5])
        d = np.linalg.norm(o[:, None] - recs[0].truth.poses[None, :, :2], axis=-1).min(1)
        assert np.max(d) < 2e-3  # every ray origin is a true scan position
        world.append(p)
    # Overlapping clouds of consecutive submaps coincide within a voxel.
    a, b = world[3], world[4]
    nn = np.linalg.norm(a[::4, None] - b[None], axis=-1).min(1)
    assert np.median(nn) < 0.1


def test_drift_distorts_submaps(bays):
    drifty = SimParams(
        lidar=EXACT, trajectory=TrajectoryParams(drift_xy=0.02, drift_yaw_deg_per_m=1.0)
    )
    recs = simulate(bays, ["S1"], [0], drifty)
    wb, wins = _windows(recs)
    sm = wb.submaps
    Y = _true_at(recs[0], wins[0])
    H = np.asarray(se2.anchor(Y, np.asarray(sm.X, np.float64)))
    assert np.max(np.linalg.norm(H[:, :2] - recs[0].truth.poses[0, :2], axis=1)) > 0.05
    i = sm.n - 1
    m = np.asarray(sm.mask[i])
    p = _apply(Y[i], np.asarray(sm.points[i], np.float64)[m])
    assert np.percentile(_dist_to_segments(p, bays.segments), 95) > 0.01


def test_determinism_and_independent_runs(bays):
    a = simulate(bays, ["S1"], [1, 2])
    b = simulate(bays, ["S1"], [1, 2])
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.seq.odometry, y.seq.odometry)
        for p, q in zip(x.seq.scans, y.seq.scans, strict=True):
            np.testing.assert_array_equal(p, q)
    assert [r.meta["seed"] for r in a] == [1, 2]
    assert not np.array_equal(a[0].seq.odometry, a[1].seq.odometry)  # other seed: other drift
    # A run does not depend on what else is simulated with it.
    c = simulate(bays, ["S1"], [2])[0]
    np.testing.assert_array_equal(c.seq.odometry, a[1].seq.odometry)
    np.testing.assert_array_equal(c.seq.scans[5], a[1].seq.scans[5])


def test_odometry_restart_rezeroes_the_frame(bays):
    recs = simulate(bays, ["S1"], [0], dataclasses.replace(CLEAN, restart_at=0.5))
    odo, true = recs[0].seq.odometry, recs[0].truth.poses
    r = int(round(0.5 * (len(odo) - 1)))
    np.testing.assert_allclose(odo[r], 0.0, atol=1e-6)
    # Before and after, odometry is rigidly related to the truth, by different anchors.
    before = np.asarray(se2.anchor(true[:r], odo[:r]))
    after = np.asarray(se2.anchor(true[r:], odo[r:]))
    np.testing.assert_allclose(before, before[:1].repeat(len(before), 0), atol=1e-3)
    np.testing.assert_allclose(after, after[:1].repeat(len(after), 0), atol=1e-3)
    assert np.hypot(*(before[0, :2] - after[0, :2])) > 5.0
    with pytest.raises(ValueError, match="restart_at"):
        SimParams(restart_at=1.5)


def test_odometry_latency_lags_the_scans(bays):
    late_by = 0.3
    a = simulate(bays, ["S1"], [0], CLEAN)[0]
    b = simulate(bays, ["S1"], [0], dataclasses.replace(CLEAN, odom_latency=late_by))[0]
    t, odo, lag = a.seq.times, a.seq.odometry, b.seq.odometry
    np.testing.assert_array_equal(b.seq.scans[7], a.seq.scans[7])  # the scans are the same
    first = t < t[0] + late_by
    np.testing.assert_allclose(lag[first], odo[:1].repeat(first.sum(), 0), atol=1e-9)
    # Each later scan carries the odometry of late_by seconds before it.
    for i in np.flatnonzero(~first)[::7]:
        j = np.searchsorted(t, t[i] - late_by) - 1
        w = (t[i] - late_by - t[j]) / (t[j + 1] - t[j])
        np.testing.assert_allclose(lag[i, :2], (1 - w) * odo[j, :2] + w * odo[j + 1, :2],
                                   atol=1e-9)  # fmt: skip
    moving = np.linalg.norm(np.diff(odo[:, :2], axis=0), axis=1) > 0
    assert np.linalg.norm(lag[1:, :2] - odo[1:, :2], axis=1)[moving].min() > 0.1  # 0.3 s at 0.5 m/s
    with pytest.raises(ValueError, match="odom_latency"):
        SimParams(odom_latency=-0.1)


def test_unknown_trajectory_and_empty_inputs(bays):
    with pytest.raises(KeyError, match="no trajectory 'T9'"):
        simulate(bays, ["T9"])
    with pytest.raises(ValueError, match="needs a trajectory and a seed"):
        simulate(bays, ["S1"], [])
    with pytest.raises(ValueError, match="crop_radius"):
        W.WindowParams(crop_radius=-1.0)
