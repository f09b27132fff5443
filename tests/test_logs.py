"""Real laser logs as benchmark recordings (``sources.logs``) and the CARMEN formats they use."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mfcl_jax import se2
from mfcl_jax.io import DataError, read_carmen
from mfcl_jax.io.carmen import beam_angles
from mfcl_jax.sources.heldout import recorded_scans
from mfcl_jax.sources.logs import DATA, LOGS, bag_recordings, log_recordings, read_log
from mfcl_jax.sources.logwindows import plan_windows

needs_data = pytest.mark.skipif(
    not (DATA / "laser").is_dir(),
    reason=f"real data folder {DATA / 'laser'} is absent (see shared/data/SOURCES.md)",
)


def _flaser(ranges, t, pose=(1.0, 2.0, 0.5)) -> str:
    vals = " ".join(f"{r:g}" for r in ranges)
    p = " ".join(f"{v:g}" for v in pose)
    return f"FLASER {len(ranges)} {vals} {p} {p} {t:g} host {t:g}\n"


# ----------------------------------------------------------------------------- formats
def test_sick_no_return_codes_are_dropped(tmp_path):
    r = np.full(181, 2.0)
    r[[3, 4, 5, 6]] = [32.767, 32.759, 81.91, 81.83]
    r[7] = 32.5  # a real long echo stays
    f = tmp_path / "a.log"
    f.write_text(_flaser(r, 1.0) + _flaser(r, 2.0))
    log = read_carmen(f)
    assert [len(s) for s in log.scans] == [177, 177]
    assert np.isclose(np.hypot(*log.scans[0].T).max(), 32.5)


@pytest.mark.parametrize(
    "n,step_deg,last_deg", [(180, 1.0, 89.0), (181, 1.0, 90.0), (360, 0.5, 89.5), (361, 0.5, 90.0)]
)
def test_beam_conventions_of_the_four_logs(n, step_deg, last_deg):
    a = np.rad2deg(beam_angles(n))
    assert a[0] == pytest.approx(-90.0) and a[-1] == pytest.approx(last_deg)
    assert np.allclose(np.diff(a), step_deg)


def test_log_without_clock(tmp_path):
    f = tmp_path / "noclock.log"
    f.write_text("".join(_flaser([1.0] * 181, 0.0) for _ in range(3)))
    with pytest.raises(DataError, match=r"noclock\.log: all 3 FLASER timestamps equal 0"):
        read_carmen(f)
    log = read_carmen(f, untimed_period=0.5)
    assert not log.timed and np.allclose(log.times, [0.0, 0.5, 1.0])


def test_bag_truth_blends_matched_poses():
    from types import SimpleNamespace

    from mfcl_jax.sources.bagtruth import truth_at_scans

    t = np.arange(50, dtype=np.float64)
    odo = np.stack([0.3 * t, np.sin(0.2 * t), 0.05 * t], -1)
    # The odometry frame drifts linearly in yaw against the truth: C(t) = (1, -2, 0.004 t).
    c = np.stack([np.ones(50), -2 * np.ones(50), 0.004 * t], -1)
    true = np.asarray(se2.compose(c, odo), np.float64)
    bag = SimpleNamespace(times=t, odometry=odo)
    anchors = np.arange(0, 50, 7)
    got, gap = truth_at_scans(bag, np.arange(50), anchors, true[anchors])
    assert np.allclose(got[anchors], true[anchors], atol=1e-4)
    assert np.abs(got - true).max() < 0.02  # between matches: far below the drift (0.03 rad)
    assert gap.max() == 3.0 and np.all(gap[anchors] == 0)


# ----------------------------------------------------------------------------- windows
def test_plan_windows_spread_disjoint_and_too_short():
    s = np.arange(0.0, 100.5, 1.0)  # 100 m, a scan every metre
    ws = plan_windows(s, 3, 30.0, "toy")
    assert [w.first for w in ws] == [0, 35, 70] and all(w.travel_m == 30.0 for w in ws)
    assert all(a.last < b.first for a, b in zip(ws[:-1], ws[1:], strict=True))
    assert ws[1].held_out == (33, 67)  # 2 m margin either side
    with pytest.raises(
        ValueError, match=r"log 'toy' is too short: 100\.0 m .* of 30 m; requested 4"
    ):
        plan_windows(s, 4, 30.0, "toy")
    with pytest.raises(ValueError, match="n_windows"):
        plan_windows(s, 0, 30.0, "toy")


# ----------------------------------------------------------------------------- real logs
@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("maps")


@pytest.fixture(scope="module")
def seattle(cache):
    return log_recordings("seattle", 2, 60.0, cache_dir=cache)


@needs_data
def test_log_formats():
    beams = {"intel": 180, "freiburg-101": 360, "orebro": 181, "seattle": 361}
    for name in LOGS:
        log = read_log(name)
        assert max(len(s) for s in log.scans) == beams[name]
        r = np.concatenate([np.hypot(*s.T) for s in log.scans])
        assert r.max() < 50.0 and not np.any((r > 32.75) & (r < 32.77))
        assert log.timed == (name != "orebro")
        if not log.timed:
            assert np.array_equal(log.times, np.arange(len(log), dtype=np.float64))


@needs_data
def test_too_short_is_an_error_before_any_work(tmp_path):
    with pytest.raises(ValueError, match=r"log 'seattle' is too short: 190\.\d m .*requested 4"):
        log_recordings("seattle", 4, 60.0, cache_dir=tmp_path)
    with pytest.raises(ValueError, match=r"log 'orebro' is too short: 221\.\d m .* of 500 m"):
        log_recordings("orebro", 1, 500.0, cache_dir=tmp_path)
    with pytest.raises(ValueError, match="unknown log 'mars'"):
        log_recordings("mars", 1, cache_dir=tmp_path)
    with pytest.raises(ValueError, match="read-only data folder"):
        log_recordings("seattle", 1, cache_dir=DATA / "laser")
    assert not any(tmp_path.iterdir())


@needs_data
def test_windows_length_and_held_out_map(seattle):
    assert [r.name for r in seattle] == ["log-seattle/w00", "log-seattle/w01"]
    (a0, a1), (b0, b1) = (r.meta["log_scans"] for r in seattle)
    assert a1 < b0
    for r in seattle:
        m = r.meta
        travel = float(np.sum(np.hypot(*np.diff(r.truth.poses[:, :2], axis=0).T)))
        assert 60.0 <= travel < 61.0 and m["travel_m"] == pytest.approx(travel, abs=0.01)
        assert m["family"] == "log:seattle" and m["map_res"] == 0.10 and m["length_m"] == 60.0
        assert m["clock"] == "log"
        used = recorded_scans(m["map_file"])
        lo, hi = m["held_out"]
        assert lo <= m["log_scans"][0] and m["log_scans"][1] <= hi
        # The map saw every scan of the log except the held-out stretch, and none of it.
        assert np.array_equal(used, np.setdiff1d(np.arange(241), np.arange(lo, hi + 1)))
        assert m["map_coverage"] > 0.85


@needs_data
def test_odometry_starts_at_identity_and_drifts_as_asked(seattle, cache):
    e = []
    for r in seattle:
        assert np.array_equal(r.seq.times, r.truth.times)
        assert np.allclose(r.seq.odometry[0], 0.0, atol=1e-5)
        y, x = r.truth.poses, r.seq.odometry
        d_true = np.asarray(se2.between(y[:-1], y[1:]), np.float64)
        d_odo = np.asarray(se2.between(x[:-1], x[1:]), np.float64)
        length = np.hypot(d_true[:, 0], d_true[:, 1])
        err = np.asarray(se2.between(d_true, d_odo), np.float64)
        ok = length > 0.2
        e.append(err[ok] / length[ok, None])
    e = np.concatenate(e)
    assert len(e) > 100
    assert np.std(e[:, :2]) == pytest.approx(0.01, rel=0.2)
    assert np.std(e[:, 2]) == pytest.approx(math.radians(0.5), rel=0.2)
    # Without drift the odometry is the true motion, seen from the first pose.
    (r,) = log_recordings("seattle", 1, 60.0, drift_xy=0.0, drift_yaw_deg=0.0, cache_dir=cache)
    rel = np.asarray(se2.between(r.truth.poses[0], r.truth.poses), np.float64)
    assert np.allclose(r.seq.odometry[:, :2], rel[:, :2], atol=1e-4)


@needs_data
def test_cache_gives_identical_floorplan(seattle, cache):
    files = {p: p.stat().st_mtime_ns for p in cache.iterdir()}
    again = log_recordings("seattle", 2, 60.0, cache_dir=cache, seed=1)
    assert {p: p.stat().st_mtime_ns for p in cache.iterdir()} == files
    for a, b in zip(seattle, again, strict=True):
        fa, fb = a.floorplan, b.floorplan
        assert [r.name for r in fa.rooms] == [r.name for r in fb.rooms]
        assert all(p.polygon.equals(q.polygon) for p, q in zip(fa.rooms, fb.rooms, strict=True))
        assert len(fa.wall_polygons) == len(fb.wall_polygons)
        assert all(p.equals(q) for p, q in zip(fa.wall_polygons, fb.wall_polygons, strict=True))
        # Another seed changes the drift, not the window.
        assert np.array_equal(a.truth.poses, b.truth.poses)
        assert not np.allclose(a.seq.odometry, b.seq.odometry)


@needs_data
def test_fine_map(cache):
    (r,) = log_recordings("seattle", 1, 30.0, map_res=0.05, cache_dir=cache)
    assert "_r50mm_" in r.meta["map_file"] and r.meta["map_res"] == 0.05
    assert r.meta["map_coverage"] > 0.85 and len(r.floorplan.rooms) >= 1


@needs_data
def test_bag_window(cache):
    (r,) = bag_recordings(1, 60.0, cache_dir=cache)
    m = r.meta
    assert m["family"] == "bag:intel" and r.name == "bag-intel/w00"
    used = recorded_scans(m["map_file"])
    assert used.min() > m["held_out"][1] and len(used) == 910 - m["held_out"][1] - 1
    assert np.array_equal(r.seq.times, r.truth.times) and len(r.seq) > 1000
    assert np.allclose(r.seq.odometry[0], 0.0, atol=1e-6)
    assert m["truth_gap_s"] < 10.0 and 700 < m["truth_matches"] <= 910
    travel = float(np.sum(np.hypot(*np.diff(r.truth.poses[:, :2], axis=0).T)))
    assert travel > 55.0
    # The bag's own odometry follows the true motion over short stretches.
    k = np.arange(0, len(r.seq) - 20, 20)
    d_true = np.asarray(se2.between(r.truth.poses[k], r.truth.poses[k + 20]), np.float64)
    d_odo = np.asarray(se2.between(r.seq.odometry[k], r.seq.odometry[k + 20]), np.float64)
    assert np.median(np.hypot(*(d_true - d_odo)[:, :2].T)) < 0.1
