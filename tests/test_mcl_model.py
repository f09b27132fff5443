"""MCL peer's models: motion (odometry increments, noise), scan likelihood and beams, the
off-map check, low-variance resampling and the initial particles."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from mfcl_jax import se2
from mfcl_jax.peers import mcl_model as mm
from mfcl_jax.sim import LidarParams, cast, sample_path, scan_points
from mfcl_jax.sim.scenes import get_scene


# ----------------------------------------------------------------------------- motion model
def _odometry_walk(rng, n=30):
    """Odometry poses with forward, backward, sideways steps and turns in place."""
    x = [np.array([1.0, -2.0, 0.3])]
    for i in range(n):
        kind = i % 4
        if kind == 3:
            inc = np.array([0.0, 0.0, rng.uniform(-0.5, 0.5)])
        else:
            step = rng.uniform(0.05, 0.4) * (-1.0 if kind == 1 else 1.0)
            side = rng.uniform(-0.1, 0.1) if kind == 2 else 0.0
            inc = np.array([step, side, rng.uniform(-0.2, 0.2)])
        x.append(np.asarray(se2.compose(x[-1], inc), np.float64))
    return np.stack(x)


def test_motion_without_noise_composes_the_odometry_increments():
    rng = np.random.default_rng(0)
    X = _odometry_walk(rng)
    p0 = jnp.asarray(rng.uniform([-5, -5, -np.pi], [5, 5, np.pi], (16, 3)), jnp.float32)
    p = p0
    zero = jnp.zeros(4, jnp.float32)
    move = jax.jit(mm.sample_motion)
    for t in range(1, len(X)):
        p = move(jax.random.PRNGKey(t), p, jnp.asarray(X[t - 1]), jnp.asarray(X[t]), zero)
    want = se2.compose(p0, se2.between(X[0], X[-1])[None])
    dxy, dyaw = se2.distance_pair(p, want)
    assert float(jnp.max(dxy)) < 1e-3 and float(jnp.max(dyaw)) < 1e-4


def test_motion_noise_spreads_the_cloud_as_it_travels():
    p = jnp.zeros((2000, 3), jnp.float32)
    alpha = jnp.full(4, 0.05, jnp.float32)
    spread = []
    move = jax.jit(mm.sample_motion)
    w = jnp.full(2000, 1 / 2000, jnp.float32)
    for t in range(40):
        prev, cur = jnp.array([0.25 * t, 0.0, 0.0]), jnp.array([0.25 * (t + 1), 0.0, 0.0])
        p = move(jax.random.PRNGKey(t), p, prev, cur, alpha)
        _, std_xy, std_yaw, _ = mm.cloud_stats(p, w)
        spread.append((float(std_xy), float(std_yaw)))
    s = np.array(spread)
    assert 0 < s[4, 0] < s[19, 0] < s[39, 0]
    assert 0 < s[4, 1] < s[19, 1] < s[39, 1]
    # Zero-mean noise: no sideways or heading bias (heading noise shortens the mean advance).
    mean = se2.mean_pose(p, axis=0)
    assert 8.0 < float(mean[0]) < 10.1
    assert abs(float(mean[1])) < 0.3 and abs(float(mean[2])) < 0.05


# ----------------------------------------------------------------------------- scan model
def test_scan_likelihood_is_highest_at_the_true_pose():
    scene = get_scene("three_rooms")
    poses = sample_path(scene.trajectories["T1"]).poses[5::60]
    pts = np.asarray(scan_points(cast(poses, scene.segments, LidarParams())))  # with clutter
    r = scene.floorplan.rasterize()
    table = mm.likelihood_table(jnp.asarray(r.dist), 0.2, 0.9, 0.1, 40.0, 2.0)
    d = np.deg2rad(20.0)
    moves = np.array(
        [[0, 0, 0], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, d], [0, 0, -d]]
    )
    for pose, scan in zip(poses, pts, strict=True):
        ok = np.all(np.isfinite(scan), axis=1)
        beams, bmask = mm.select_beams(
            jnp.asarray(np.where(ok[:, None], scan, 0.0), jnp.float32), jnp.asarray(ok), 60
        )
        cand = jnp.asarray(pose + moves, jnp.float32)
        ll = np.asarray(mm.scan_loglik(cand, beams, bmask, table, jnp.asarray(r.origin), r.res))
        assert np.all(ll[0] > ll[1:] + 20.0), ll


def test_beams_are_picked_evenly_among_the_valid_points():
    pts = jnp.stack([jnp.arange(100.0), jnp.zeros(100)], axis=-1)
    mask = (jnp.arange(100) % 2 == 0) & (jnp.arange(100) < 80)  # 40 valid, even x
    b, m = mm.select_beams(pts, mask, 10)
    assert bool(jnp.all(m)) and bool(jnp.all(mask[b[:, 0].astype(jnp.int32)]))
    assert np.all(np.diff(np.asarray(b[:, 0])) == 8.0)  # every 4th valid point
    b, m = mm.select_beams(pts, mask, 60)  # fewer valid points than beams: each used once
    assert int(m.sum()) == 40
    assert np.array_equal(np.asarray(b[:40, 0]), np.arange(0.0, 80.0, 2.0))


def test_off_map_moves_are_detected_through_thin_walls():
    passable = jnp.ones((10, 30), bool).at[:, 10:12].set(False)  # a 0.2 m wall at x 1.0-1.2
    origin = jnp.zeros(2, jnp.float32)
    before = jnp.array([[0.9, 0.5, 0.0], [0.5, 0.5, 0.0], [0.9, 0.5, 0.0]], jnp.float32)
    after = jnp.array([[1.25, 0.5, 0.0], [0.8, 0.5, 0.0], [0.9, 1.5, 0.0]], jnp.float32)
    ok = mm.on_map(before, after, passable, origin, 0.1)
    assert ok.tolist() == [False, True, False]  # hop over the wall; inside; off the grid


# ----------------------------------------------------------------------------- resampling
_resample = jax.jit(mm.low_variance_resample)


@given(
    st.lists(st.floats(0.0, 1.0, width=32, allow_subnormal=False), min_size=1, max_size=64),
    st.integers(0, 2**31 - 1),
)
def test_low_variance_resampling_draws_floor_or_ceil_of_n_w(values, seed):
    # One shape, one compilation; zero weights pad. (Subnormal weights: XLA flushes them to 0.)
    w = np.zeros(64, np.float32)
    w[: len(values)] = values
    if w.sum() <= 0:
        w[0] = 1.0
    idx = np.asarray(_resample(jax.random.PRNGKey(seed), jnp.asarray(w)))
    n = len(w)
    assert idx.shape == (n,) and idx.min() >= 0 and idx.max() < n
    assert np.all(np.diff(idx) >= 0)
    counts = np.bincount(idx, minlength=n)
    expect = n * w / w.sum()
    assert np.all(counts >= np.floor(expect - 1e-3)) and np.all(counts <= np.ceil(expect + 1e-3))
    assert np.all(counts[w == 0] == 0)


def test_low_variance_resampling_is_unbiased_and_deterministic():
    w = jnp.asarray([0.05, 0.3, 0.0, 0.15, 0.1, 0.4, 0.0, 0.0], jnp.float32)
    keys = jax.random.split(jax.random.PRNGKey(7), 400)
    idx = jax.vmap(mm.low_variance_resample, in_axes=(0, None))(keys, w)
    mean_counts = np.mean([np.bincount(np.asarray(i), minlength=8) for i in idx], axis=0)
    np.testing.assert_allclose(mean_counts, 8 * np.asarray(w), atol=0.1)
    a = mm.low_variance_resample(jax.random.PRNGKey(3), w)
    b = mm.low_variance_resample(jax.random.PRNGKey(3), w)
    assert np.array_equal(np.asarray(a), np.asarray(b))


def test_initial_particles_are_uniform_over_the_free_cells():
    free = np.zeros((20, 40), bool)
    free[2:18, 2:10] = True  # 128 cells
    free[2:18, 20:38] = True  # 288 cells
    cdf = mm.free_cdf(jnp.asarray(free))
    origin = jnp.asarray([-1.0, 2.0], jnp.float32)
    p = np.asarray(mm.sample_free(jax.random.PRNGKey(0), cdf, free.shape, origin, 0.1, 20000))
    ix = np.floor((p[:, 0] + 1.0) / 0.1).astype(int)
    iy = np.floor((p[:, 1] - 2.0) / 0.1).astype(int)
    assert free[iy, ix].all()
    assert abs(np.mean(ix < 15) - 128 / 416) < 0.02
    assert p[:, 2].min() >= -np.pi and p[:, 2].max() <= np.pi and abs(p[:, 2].mean()) < 0.05
