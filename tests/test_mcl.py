"""MCL peer: its inputs and commits, batching, compilation, end-to-end behaviour (the models
and resampling: test_mcl_model.py)."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mfcl_jax import se2
from mfcl_jax import windows as W
from mfcl_jax.io.errors import DataError
from mfcl_jax.peers import MCLParams, commits, pad_batch, prepare_mcl_inputs, run_mcl, trace_count
from mfcl_jax.peers import mcl_model as mm
from mfcl_jax.peers.mcl import MCLTrace
from mfcl_jax.sim.scenes import get_scene
from mfcl_jax.sources.simulated import simulate as scene_recordings


def _window_ends(rec, d_s=6.0):
    return W.window_bounds(W.travelled(rec.seq.odometry), d_s, 2.0)[:, 1]


@pytest.fixture(scope="module")
def t1():
    return scene_recordings("three_rooms", ["T1"], seeds=(0,))[0]


@pytest.fixture(scope="module")
def s1():
    return scene_recordings("symmetric_bays", ["S1"], seeds=(0,))[0]


# ----------------------------------------------------------------------------- inputs
def test_window_ends_are_the_windows_of_the_one_data_path():
    (rec,) = scene_recordings("symmetric_bays", ["S1"], seeds=(0,))
    w = W.cut(rec.seq)
    np.testing.assert_array_equal(_window_ends(rec), w.bounds[:, 1])
    np.testing.assert_array_equal(w.keyframes, np.arange(len(rec.seq)))


def test_prepare_validates_indices(t1):
    with pytest.raises(DataError, match="window ends"):
        prepare_mcl_inputs([t1], [[0, len(t1.seq)]])
    with pytest.raises(DataError, match="no window ends"):
        prepare_mcl_inputs([t1], [[]])
    with pytest.raises(DataError, match="keyframe indices"):
        prepare_mcl_inputs([t1], [[0]], keyframe_indices=[[0, 5, 5]])
    with pytest.raises(DataError, match="2 window lists for 1"):
        prepare_mcl_inputs([t1], [[0], [1]])


def test_commits_apply_thresholds_and_persistence_after_the_fact():
    std = np.array([[[2.0, 0.4, 0.3, 0.6, 0.2, 0.2, 0.1, 0.1]]])
    yaw = np.full_like(std, np.deg2rad(3.0))
    yaw[..., 5] = np.deg2rad(30.0)
    trace = MCLTrace(
        pose=np.zeros((*std.shape, 3)),
        anchor=np.zeros((*std.shape, 3)),
        std_xy=std,
        std_yaw=yaw,
        ess=np.ones_like(std),
        fit=np.zeros_like(std),
        window_mask=np.array([[True] * 7 + [False]]),
    )
    got = commits(trace, 0.5, 10.0, 1)[0, 0].tolist()
    assert got == [False, True, True, False, True, False, True, False]
    got = commits(trace, 0.5, 10.0, 2)[0, 0].tolist()
    assert got == [False, False, True, False, False, False, False, False]
    assert commits(trace, 0.25, 45.0, 3)[0, 0].tolist() == [False] * 4 + [False, False, True, False]
    with pytest.raises(ValueError, match="persist"):
        commits(trace, 0.5, 10.0, 0)


# ----------------------------------------------------------------------------- batching
SMALL = MCLParams(n_particles=256, chunk=2)


def _short(rec, n, every):
    """The first ``n`` keyframes of a recording, read every ``every``."""
    return np.arange(n), np.arange(every - 1, n, every)


def test_batch_over_runs_and_seeds_equals_one_at_a_time(t1, s1):
    # Batched and single runs agree to rounding; a particle filter amplifies rounding (one
    # resampling pointer landing the other side of a boundary), so compare the first steps.
    kf, we = _short(t1, 24, 6)
    both = run_mcl(prepare_mcl_inputs([t1, s1], [we, we], [kf, kf], max_points=60), SMALL, (0, 1))
    assert both.pose.shape == (2, 2, 8, 3)
    # Swapping runs and seeds (same shapes, no compilation) swaps the results: a run's random
    # stream follows its name and the seed, not its place in the batch.
    swap = run_mcl(prepare_mcl_inputs([s1, t1], [we, we], [kf, kf], max_points=60), SMALL, (1, 0))
    for name in ("pose", "anchor", "std_xy", "std_yaw", "ess", "fit"):
        a, b = getattr(both, name), getattr(swap, name)
        np.testing.assert_allclose(a, b[::-1, ::-1], rtol=1e-3, atol=1e-3, err_msg=name)
    assert not np.allclose(both.pose[0, 0], both.pose[0, 1])  # seeds differ
    # s1 alone, in coarse buckets (the benchmark's): more runs, steps, windows and grid cells
    # than the pair's (whose grid is t1's), the same results as in the pair
    padded = pad_batch(prepare_mcl_inputs([s1], [we], [kf], max_points=60), runs=3, grid=64)
    assert padded.n_runs == 3 and padded.window_mask.shape[1] == 16
    assert padded.dist.shape[1:] != prepare_mcl_inputs([t1, s1], [we, we], [kf, kf]).dist.shape[1:]
    big = run_mcl(padded, SMALL, (1,))
    for name in ("pose", "anchor", "std_xy", "std_yaw", "ess", "fit"):
        a, c = getattr(big, name)[0, 0, :8], getattr(both, name)[1, 1]
        np.testing.assert_allclose(a, c, rtol=1e-3, atol=1e-3, err_msg=name)


def test_a_run_filtered_in_calls_of_a_few_steps_equals_one_call(t1, monkeypatch):
    # the cloud is carried from call to call: cutting the steps changes nothing, and a longer
    # recording reuses the compilation of the shorter one (one program for any length)
    from mfcl_jax.peers import mcl

    kf, we = _short(t1, 24, 6)
    batch = prepare_mcl_inputs([t1], [we], [kf], max_points=60)
    whole = run_mcl(batch, SMALL, (0,))
    monkeypatch.setattr(mcl, "STEPS", 8)
    cut = run_mcl(batch, SMALL, (0,))  # steps in three calls
    for name in ("pose", "anchor", "std_xy", "std_yaw", "ess", "fit"):
        np.testing.assert_array_equal(getattr(cut, name), getattr(whole, name), err_msg=name)
    n0 = trace_count()
    kf2, we2 = _short(t1, 40, 8)
    longer = run_mcl(prepare_mcl_inputs([t1], [we2], [kf2], max_points=60), SMALL, (0,))
    assert trace_count() == n0 and longer.pose.shape[2] >= 5


def test_thinning_scans_to_n_beams_keeps_the_filter_s_own_pick(t1):
    kf, we = _short(t1, 24, 6)
    full = prepare_mcl_inputs([t1], [we], [kf])
    thin = prepare_mcl_inputs([t1], [we], [kf], max_points=60)
    assert thin.scans.shape[2] == 64 < full.scans.shape[2]
    pick = jax.vmap(mm.select_beams, in_axes=(0, 0, None))
    a, ma = pick(jnp.asarray(full.scans[0]), jnp.asarray(full.mask[0]), 60)
    b, mb = pick(jnp.asarray(thin.scans[0]), jnp.asarray(thin.mask[0]), 60)
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    np.testing.assert_array_equal(np.asarray(ma), np.asarray(mb))
    cropped = prepare_mcl_inputs([t1], [we], [kf], crop_radius=5.0)
    r = np.hypot(cropped.scans[..., 0], cropped.scans[..., 1])
    assert np.all(r[cropped.mask] <= 5.0) and cropped.mask.sum() < full.mask.sum()


def test_traced_parameters_and_thresholds_do_not_recompile(t1, s1):
    # the batch test's shapes, seeds included: its compilation is reused
    kf, we = _short(t1, 24, 6)
    batch = prepare_mcl_inputs([t1, s1], [we, we], [kf, kf], max_points=60)
    trace = run_mcl(batch, SMALL, seeds=(0, 1))
    n0 = trace_count()
    other = dataclasses.replace(
        SMALL,
        alpha=(0.1, 0.02, 0.1, 0.02),
        sigma_hit=0.3,
        temper=0.1,
        resample_ess=0.8,
        off_map=5.0,
        recovery_alpha_slow=0.02,
        recovery_alpha_fast=0.2,
    )
    again = run_mcl(batch, other, seeds=(1, 2))
    for xy in (0.1, 0.5, 2.0):
        commits(again, xy, 5.0, 2)
    assert trace_count() == n0
    assert not np.allclose(again.pose, trace.pose)
    run_mcl(batch, dataclasses.replace(SMALL, n_particles=128), seeds=(0, 1))
    assert trace_count() == n0 + 1


# ----------------------------------------------------------------------------- end to end
GLOBAL = MCLParams(n_particles=16384)


def test_converges_on_three_rooms_by_the_end_of_the_walk(t1):
    we = _window_ends(t1)
    trace = run_mcl(prepare_mcl_inputs([t1], [we], max_points=60), GLOBAL, seeds=(0,))
    dxy, dyaw = se2.distance_pair(trace.pose[0, 0, : len(we)], t1.truth.poses[we])
    assert float(dxy[-1]) < 1.0 and float(dyaw[-1]) < np.deg2rad(5.0)
    assert commits(trace, 0.5, 10.0)[0, 0, len(we) - 1]
    # The anchor places the odometry where the mean pose is: P = A X.
    X = t1.seq.odometry[we[-1]]
    np.testing.assert_allclose(
        se2.compose(trace.anchor[0, 0, len(we) - 1], X), trace.pose[0, 0, len(we) - 1], atol=1e-3
    )


def test_symmetric_bays_middle_walk_stays_multimodal_without_long_views():
    """A walk inside the middle bays R2-R3 that never comes near a sealed end wall.

    With the scans cropped at 10 m (the evidence our windows keep) the cloud stays spread over
    the lattice of bays. With the LiDAR's full 40 m the beams along the door line pass through
    every aligned door to the end walls, and the filter localizes correctly: the bays are
    ambiguous only for short-range evidence. (Seed-specific behaviour, checked on 3 seeds; with
    8192 particles some seeds instead lock on the bay one pitch away, a false commit.)
    """
    sb = get_scene("symmetric_bays")
    wp = np.array([[9.5, 4.2], [12.5, 1.8], [17.0, 1.8], [19.0, 4.5], [20.5, 4.5]])
    scene = dataclasses.replace(sb, trajectories={"mid": wp})
    (rec,) = scene_recordings(scene, seeds=(0,))
    we = _window_ends(rec)[:3]
    seeds = (0, 1, 2)
    cropped = run_mcl(
        prepare_mcl_inputs([rec], [we], max_points=60, crop_radius=10.0), GLOBAL, seeds
    )
    assert np.all(cropped.std_xy[0, :, :3] > 1.0)
    assert not commits(cropped, 0.5, 10.0).any()
    full = run_mcl(prepare_mcl_inputs([rec], [we], max_points=60), GLOBAL, seeds)
    dxy, _ = se2.distance_pair(full.pose[0, :, 2], rec.truth.poses[we[2]])
    assert np.all(full.std_xy[0, :, 2] < 0.5) and np.all(np.asarray(dxy) < 0.5)
