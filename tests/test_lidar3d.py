"""3-D LiDAR: the multi-ring ray caster, floor detection and the height-band slicer."""

from __future__ import annotations

from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mfcl_jax.io.errors import DataError
from mfcl_jax.sim.lidar3d import Lidar3DParams, _cast3d_jit, beam_directions, cast3d, livox_mid360
from mfcl_jax.sim.raycast import LidarParams, cast, scan_points
from mfcl_jax.sim.scenes import Scene, rect_segments, symmetric_bays, three_rooms
from mfcl_jax.sim.world3d import build_geometry, first_hit
from mfcl_jax.sources.cloud3d import BandParams, Mount, slice_cloud, slice_clouds
from mfcl_jax.sources.floor import detect_floor
from mfcl_jax.sources.simulated import simulate_walk
from mfcl_jax.sources.walk3d import walk3d

ROOM = rect_segments(0.0, 0.0, 10.0, 10.0)  # a 10 m x 10 m room
H_CEIL = 3.0
# The sensor of the slicing tests: Livox-like rings, fewer azimuths (one compilation).
LIVOX = livox_mid360(n_azimuth=256, height=0.5)


_first_hit = jax.jit(first_hit)


def _hit(origin, el_deg, az_deg, geom):
    el, az = np.deg2rad(el_deg), np.deg2rad(az_deg)
    d = jnp.array([[np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]], jnp.float32)
    return float(_first_hit(jnp.asarray(origin, jnp.float32), d, geom)[0])


def _seg_dist(p, segs):
    """Distance of points ``(n, 2)`` to the nearest segment ``(M, 2, 2)``."""
    a, e = segs[:, 0], segs[:, 1] - segs[:, 0]
    w = p[:, None] - a[None]
    u = np.clip(np.sum(w * e, -1) / np.sum(e * e, -1), 0, 1)
    return np.min(np.linalg.norm(w - u[..., None] * e, axis=-1), axis=1)


# ------------------------------------------------------------------------- the ray caster
def test_beams_hit_floor_wall_ceiling_at_the_right_range():
    g = build_geometry(ROOM, h_ceil=H_CEIL)
    o = (5.0, 5.0, 1.0)
    assert _hit(o, 0.0, 0.0, g) == pytest.approx(5.0, abs=1e-4)  # wall x = 10, horizontally
    assert _hit(o, -30.0, 0.0, g) == pytest.approx(2.0, abs=1e-4)  # floor: 1 m / sin 30
    assert _hit(o, 30.0, 0.0, g) == pytest.approx(4.0, abs=1e-4)  # ceiling: 2 m / sin 30
    assert _hit(o, -90.0 + 1e-3, 0.0, g) == pytest.approx(1.0, abs=1e-4)  # straight down
    # A shallow upward beam reaches the wall below the ceiling: 5 m / cos 10.
    assert _hit(o, 10.0, 90.0, g) == pytest.approx(5.0 / np.cos(np.deg2rad(10)), abs=1e-4)


def test_beam_aimed_at_a_table_hits_its_top_and_passes_over_a_low_one():
    table = rect_segments(5.2, 4.7, 5.8, 5.3)
    o = (5.0, 5.0, 1.0)
    g = build_geometry(ROOM, table, [0.75] * 4, h_ceil=H_CEIL)
    assert int(g.cap_valid.sum()) == 2  # the lid: two triangles
    # -30 deg reaches z = 0.75 after 0.433 m horizontally, over the table top.
    assert _hit(o, -30.0, 0.0, g) == pytest.approx(0.5, abs=1e-4)
    # The same table at 0.2 m: the beam passes over it to the floor.
    low = build_geometry(ROOM, table, [0.2] * 4, h_ceil=H_CEIL)
    assert _hit(o, -30.0, 0.0, low) == pytest.approx(2.0, abs=1e-4)
    # A horizontal beam at 1 m passes over the 0.75 m table, not over a 1.2 m cabinet.
    assert _hit(o, 0.0, 0.0, g) == pytest.approx(5.0, abs=1e-4)
    tall = build_geometry(ROOM, table, [1.2] * 4, h_ceil=H_CEIL)
    assert _hit(o, 0.0, 0.0, tall) == pytest.approx(0.2, abs=1e-4)


@given(
    x=st.floats(0.5, 9.5),
    y=st.floats(0.5, 9.5),
    z=st.floats(0.1, 2.9),
    el=st.floats(-80.0, 80.0),
    az=st.floats(-180.0, 180.0),
)
def test_every_hit_lies_on_a_surface_of_the_room(x, y, z, el, az):
    r = _hit((x, y, z), el, az, build_geometry(ROOM, h_ceil=H_CEIL))
    e, a = np.deg2rad(el), np.deg2rad(az)
    p = np.array([x, y, z]) + r * np.array(
        [np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)]
    )
    on = [abs(p[0]), abs(p[0] - 10), abs(p[1]), abs(p[1] - 10), abs(p[2]), abs(p[2] - H_CEIL)]
    assert min(on) < 1e-3 * max(1.0, r)
    assert np.all(p >= -1e-3) and np.all(p[:2] <= 10 + 1e-3) and p[2] <= H_CEIL + 1e-3


def test_beam_directions_are_unit_and_ring_major():
    d = np.asarray(beam_directions(jnp.deg2rad(jnp.array([-7.0, 52.0])), 8))
    assert d.shape == (16, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(np.rad2deg(np.arcsin(d[:8, 2])), -7.0, atol=1e-4)


def test_cast3d_compiles_once_for_new_values_and_culling_is_exact():
    s = three_rooms()
    g = build_geometry(s.floorplan.wall_faces, s.clutter, s.clutter_height, 2.8)
    assert int(g.cap_valid.sum()) == 32  # 16 boxes below the ceiling, 2 triangles each
    pose = np.array([[20.0, 6.0, 0.4]])
    full = np.asarray(cast3d(pose, g, LIVOX))
    n0 = _cast3d_jit._cache_size()
    again = np.asarray(cast3d(pose, g, replace(LIVOX, height=1.2)))
    assert _cast3d_jit._cache_size() == n0  # a new height is a traced value
    assert np.isfinite(again[:, :, 0]).mean() > 0.9
    # Culling to the 32 nearest faces: every return kept is the full cast's return.
    cut = np.asarray(cast3d(pose, g, LIVOX, max_faces=32))
    both = np.isfinite(cut[..., 0]) & np.isfinite(full[..., 0])
    assert both.sum() > 0.3 * np.isfinite(full[..., 0]).sum()
    assert np.all(~np.isfinite(cut[..., 0]) | both)
    np.testing.assert_allclose(cut[both], full[both], atol=1e-5)


# ---------------------------------------------------------------------------- slicing
def _room_cloud(sensor=LIVOX, pose=(4.0, 6.0, 0.3), seed=0):
    g = build_geometry(ROOM, h_ceil=2.8)
    return np.asarray(cast3d(np.asarray([pose]), g, sensor, key=jax.random.PRNGKey(seed)))[0]


def test_band_keeps_walls_and_removes_floor_and_ceiling():
    cloud = _room_cloud()
    whole = BandParams(z_min=-1.0, z_max=4.0)
    xy, info = slice_cloud(cloud, whole)
    assert info.floor.height == pytest.approx(0.5, abs=0.02)
    assert info.ceiling == pytest.approx(2.8, abs=0.05)
    assert info.n_floor > 300 and info.n_ceiling > 1000
    # Every kept point is on a wall (the sensor frame is the room frame moved by the pose).
    c, s = np.cos(0.3), np.sin(0.3)
    world = xy @ np.array([[c, s], [-s, c]]) + [4.0, 6.0]
    assert np.percentile(_seg_dist(world, ROOM), 99) < 0.05
    raw = cloud[np.all(np.isfinite(cloud), 1), :2] @ np.array([[c, s], [-s, c]]) + [4.0, 6.0]
    assert np.mean(_seg_dist(raw, ROOM) > 0.1) > 0.3  # what the band removed: floor, ceiling


def test_floor_detection_under_a_3_degree_tilt():
    for roll, pitch in ((0.0, 3.0), (2.0, -2.0)):
        tilted = replace(LIVOX, roll_deg=roll, pitch_deg=pitch)
        cloud = _room_cloud(tilted)
        f = detect_floor(cloud[np.all(np.isfinite(cloud), 1)])
        assert f.tilt_deg == pytest.approx(np.hypot(roll, pitch), abs=0.2)
        assert f.height == pytest.approx(0.5, abs=0.02)
        xy, info = slice_cloud(cloud)
        assert info.n_kept > 500
        assert np.percentile(np.hypot(*xy.T), 1) > 0.3


def test_mount_correction_gives_the_untilted_slice():
    pose = (4.0, 6.0, 0.3)
    level = _room_cloud(pose=pose)
    tilted = _room_cloud(replace(LIVOX, pitch_deg=10.0), pose=pose)
    mount = Mount(rpy=(0.0, np.deg2rad(10.0), 0.0))
    for band in (BandParams(), BandParams(z_min=0.3, z_max=1.2, relative_to="sensor")):
        a, _ = slice_cloud(level, band)
        b, info = slice_cloud(tilted, band, mount=mount)
        assert info.floor.tilt_deg < 0.2
        assert len(b) > 0.5 * len(a)
        # The two slices lie on the same walls: each point near the other slice.
        d_ba = np.min(np.linalg.norm(b[:, None] - a[None], axis=-1), axis=1)
        d_ab = np.min(np.linalg.norm(a[:, None] - b[None], axis=-1), axis=1)
        assert np.median(d_ba) < 0.03 and np.median(d_ab) < 0.03
        assert np.percentile(d_ba, 95) < 0.1
    # Without the mount the sensor-frame band is a tilted slice: far from the level one.
    b, _ = slice_cloud(tilted, BandParams(z_min=0.3, z_max=1.2, relative_to="sensor"))
    d = np.min(np.linalg.norm(b[:, None] - a[None], axis=-1), axis=1)
    assert np.percentile(d, 95) > 0.1


def test_empty_band_and_bad_band_are_data_errors():
    cloud = _room_cloud()
    with pytest.raises(DataError, match=r"no point in the band z in \[3.50, 4.00\] m above the"):
        slice_cloud(cloud, BandParams(z_min=3.5, z_max=4.0), where="scan 7")
    with pytest.raises(DataError, match=r"span z in \[-0\.\d+, 2\.\d+\]"):
        slice_cloud(cloud, BandParams(z_min=3.5, z_max=4.0))
    with pytest.raises(DataError, match="z_min < z_max"):
        BandParams(z_min=1.0, z_max=1.0)
    with pytest.raises(DataError, match="z_min < z_max"):
        BandParams(z_min=2.0, z_max=1.0)
    with pytest.raises(DataError, match="relative_to"):
        BandParams(relative_to="ceiling")
    with pytest.raises(DataError, match=r"\(n, 3\)"):
        slice_cloud(np.zeros((5, 2)))
    with pytest.raises(DataError, match="Mount.rpy"):
        Mount(rpy=(0.0, 0.1))
    # Only points above the sensor: no floor to measure heights from ...
    up = cloud[cloud[:, 2] > -0.1]
    with pytest.raises(DataError, match="no floor plane below the sensor"):
        slice_cloud(up)
    with pytest.raises(DataError, match="in any of the 1 clouds"):
        slice_clouds([up])
    # ... unless another cloud of the same rigid sensor shows it.
    scans, infos, detected = slice_clouds([cloud, up])
    assert detected[1] is None and infos[1].floor.height == pytest.approx(0.5, abs=0.02)
    assert len(scans[1]) > 100


def test_sliced_3d_scan_matches_the_2d_ray_cast():
    s = three_rooms()
    g = build_geometry(s.floorplan.wall_faces, s.clutter, s.clutter_height, 2.8)
    pose = np.array([[20.0, 6.0, 0.4]])
    cloud = np.asarray(cast3d(pose, g, LIVOX))[0]
    xy, _ = slice_cloud(cloud)
    # The 2-D ring at the band's height: walls and the furniture taller than 0.9 m.
    segs = np.concatenate([s.floorplan.wall_faces, s.clutter[s.clutter_height > 0.9]])
    r = cast(pose, segs, LidarParams(sigma=0.0, dropout=0.0))
    p2 = np.asarray(scan_points(r), np.float64)[0]
    # The 2-D scan's walls: segments between neighbouring beams' points less than 0.3 m apart.
    nxt = np.roll(p2, -1, axis=0)
    ok = np.all(np.isfinite(p2), 1) & np.all(np.isfinite(nxt), 1)
    ok &= np.linalg.norm(nxt - p2, axis=1) < 0.3
    walls2d = np.stack([p2[ok], nxt[ok]], 1)
    d = _seg_dist(xy, walls2d)
    # Most sliced points lie on the 2-D scan's walls (the others: surfaces the 2-D ring sees
    # in a grazing or shadowed stretch); the raw projection does not.
    assert np.mean(d < 0.05) > 0.9
    raw = cloud[np.all(np.isfinite(cloud), 1), :2]
    assert np.mean(_seg_dist(raw, walls2d) < 0.05) < 0.6


# ------------------------------------------------------------------------- walks, scenes
def test_walk3d_shares_odometry_and_2d_scans_with_simulate_walk():
    fp = symmetric_bays().floorplan
    wp = np.array([[1.0, 1.8], [6.0, 1.8]])
    tiny = Lidar3DParams(elevation_deg=(-7.0, 0.0, 20.0), n_azimuth=32)
    w = walk3d(fp, wp, tiny, tag="bays")
    rec = simulate_walk(fp, wp, seed=0, tag="bays")
    t, true, odo, scans = rec.seq.times, rec.truth.poses, rec.seq.odometry, rec.seq.scans
    np.testing.assert_allclose(w.odom, odo)
    np.testing.assert_allclose(w.true, true)
    assert all(np.allclose(a, b) for a, b in zip(w.scans2d, scans, strict=True))
    assert w.clouds.shape == (len(t), 96, 3)
    sc, infos, det = slice_clouds(w.clouds, BandParams(z_min=-0.2, z_max=0.2, relative_to="sensor"))
    assert len(sc) == len(t) and all(len(x) > 0 for x in sc)


def test_scene_clutter_heights():
    s = three_rooms()
    assert s.clutter_height.shape == (len(s.clutter),)
    plain = Scene("x", s.floorplan, s.clutter[:4])
    np.testing.assert_array_equal(plain.clutter_height, 1.0)
    with pytest.raises(ValueError, match="clutter_height"):
        Scene("x", s.floorplan, s.clutter[:4], clutter_height=[1.0, 2.0])
    with pytest.raises(ValueError, match="clutter_height"):
        Scene("x", s.floorplan, s.clutter[:4], clutter_height=[1.0, 0.0, 1.0, 1.0])
