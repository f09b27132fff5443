"""LiDAR odometry (``scanmatch``): keyframe poses refined by scan-to-local-map ICP."""

from __future__ import annotations

import dataclasses

import numpy as np

from mfcl_jax import se2
from mfcl_jax import windows as W
from mfcl_jax.score import pose_at
from mfcl_jax.sim import SimParams
from mfcl_jax.sim.trajectory import TrajectoryParams
from mfcl_jax.sources.simulated import simulate
from mfcl_jax.windows.icp import ScanMatchParams, thin_scan
from mfcl_jax.windows.odometry import Odometer, scan_match


def _drifting(drift_xy=0.03, drift_yaw=2.0, seed=0):
    """A three_rooms walk whose odometry drifts like a robot's wheels (3 %, 2 deg/m)."""
    tp = TrajectoryParams(drift_xy=drift_xy, drift_yaw_deg_per_m=drift_yaw)
    return simulate("three_rooms", ["T1"], [seed], SimParams(trajectory=tp))[0]


def _window_errors(w, rec):
    """Per window: |relative pose error| (m, deg) between its first and last keyframe."""
    kt = np.asarray(rec.seq.times)[w.keyframes]
    Y = pose_at(rec.truth.times, rec.truth.poses, kt)
    e_xy, e_th = [], []
    for j0, j1 in w.bounds:
        rel_true = se2.compose_host(se2.inverse_host(Y[j0]), Y[j1])
        rel_odo = se2.compose_host(se2.inverse_host(w.odometry[j0]), w.odometry[j1])
        d = se2.compose_host(se2.inverse_host(rel_true), rel_odo)
        e_xy.append(np.hypot(d[0], d[1]))
        e_th.append(abs(np.degrees(d[2])))
    return np.asarray(e_xy), np.asarray(e_th)


def test_scan_matching_removes_wheel_drift_inside_windows():
    rec = _drifting()
    off = W.cut(rec.seq, W.WindowParams(scan_match=ScanMatchParams(enabled=False)))
    on = W.cut(rec.seq, W.WindowParams())
    np.testing.assert_array_equal(off.bounds, on.bounds)  # the input odometry cuts the windows
    raw_xy, raw_th = _window_errors(off, rec)
    sm_xy, sm_th = _window_errors(on, rec)
    # The drift bends a 6 m window by a decimetre and degrees (median 0.10 m, 1.5 deg at
    # seed 0); matched, by centimetres and tenths of a degree (0.02 m, 0.2 deg).
    assert np.median(raw_th) > 1.0 and np.median(raw_xy) > 0.05
    assert np.median(sm_th) < 0.5 and np.median(sm_xy) < 0.04
    assert np.median(sm_xy) < 0.3 * np.median(raw_xy)
    assert np.median(sm_th) < 0.3 * np.median(raw_th)
    # The windows' input-frame poses are the input odometry's.
    np.testing.assert_allclose(on.X_input, rec.seq.odometry[on.last_scan()])
    np.testing.assert_allclose(off.X, off.X_input)


def test_refined_odometry_starts_at_the_input_and_is_causal():
    rec = _drifting(seed=1)
    seq = rec.seq
    kf = W.keyframes(seq.odometry)
    raw = seq.odometry[kf]
    seg = W.odometry_segments(raw, seq.times[kf])
    scans = [seq.scans[i] for i in kf]
    whole = scan_match(scans, raw, seg)
    np.testing.assert_allclose(whole[0], raw[0], atol=1e-6)
    odo = Odometer()
    for a, b in ((0, 7), (7, 40), (40, 41), (41, len(kf))):  # chunks of any size, in order
        part = odo.extend(scans[a:b], raw[a:b], seg[a:b])
    np.testing.assert_array_equal(part, whole)


def test_cutting_many_recordings_at_once_equals_cutting_each():
    """``cut_many`` cuts recordings in one batched LiDAR odometry (padded to ``rows``) or in
    turn: every window must be what cutting that recording alone gives."""
    recs = [_drifting(seed=s) for s in (1, 2)]
    wp = W.WindowParams(d_s=6.0)
    batched = W.cut_many(((r.seq, wp) for r in recs), rows=4, together=True)
    in_turn = W.cut_many(((r.seq, wp) for r in recs), together=False)
    for r, w in zip(recs * 2, batched + in_turn, strict=True):
        one = W.cut(r.seq, wp)
        np.testing.assert_array_equal(w.odometry, one.odometry)
        np.testing.assert_array_equal(w.keyframes, one.keyframes)
        assert len(w) == len(one) > 0
        for a, b in zip(w.points, one.points, strict=True):
            np.testing.assert_array_equal(a, b)


def test_scans_without_structure_keep_the_input_increments():
    rec = _drifting(seed=2)
    seq = rec.seq
    kf = W.keyframes(seq.odometry)[:50]
    raw = seq.odometry[kf]
    empty = [np.full((20, 2), np.nan)] * len(kf)
    odo = Odometer()
    out = odo.extend(empty, raw, np.zeros(len(kf), int))
    assert not odo.trusted.any()
    np.testing.assert_allclose(out[:, :2], raw[:, :2], atol=1e-4)


def test_an_odometry_jump_restarts_at_the_input_pose():
    rec = _drifting(seed=3)
    seq = rec.seq
    kf = W.keyframes(seq.odometry)
    raw = seq.odometry[kf].copy()
    raw[60:, :2] += 500.0  # a restart: the input frame jumps
    seg = W.odometry_segments(raw, seq.times[kf])
    assert seg[59] != seg[60]
    out = scan_match([seq.scans[i] for i in kf], raw, seg)
    np.testing.assert_allclose(out[60], raw[60], atol=1e-3)
    assert np.hypot(*(out[60, :2] - out[59, :2])) > 400.0  # the jump stays visible


def _rezeroed(seq, at, step=(0.3, 0.0), turn_deg=90.0):
    """``seq`` whose odometry restarts at scan ``at`` in a frame placed so that the input's
    step there is small (``step`` m, ``turn_deg``): a restart the step test cannot see."""
    from mfcl_jax.sources import ScanSequence

    odo = np.asarray(seq.odometry, np.float64)
    rel = np.stack([se2.compose_host(se2.inverse_host(odo[at]), o) for o in odo[at:]])
    start = se2.compose_host(odo[at - 1], np.array([*step, np.deg2rad(turn_deg)]))
    out = odo.copy()
    out[at:] = [se2.compose_host(start, r) for r in rel]
    return ScanSequence(seq.times, seq.scans, out, "rezeroed")


def test_a_restart_the_step_test_cannot_see_is_found_by_the_scans():
    rec = _drifting(seed=2, drift_xy=0.01, drift_yaw=0.5)
    kf = W.keyframes(rec.seq.odometry)
    at = int(kf[len(kf) // 2])
    seq = _rezeroed(rec.seq, at)
    kf2 = W.keyframes(seq.odometry)
    assert W.odometry_segments(seq.odometry[kf2], seq.times[kf2])[-1] == 0  # unseen by steps
    w = W.cut(seq)
    k = int(np.flatnonzero(kf2 == at)[0])
    np.testing.assert_array_equal(w.segments, (np.arange(len(kf2)) >= k).astype(int))
    assert np.all(w.segments[w.bounds[:, 0]] == w.segments[w.bounds[:, 1]])  # none straddles
    # the same walk without the restart is one segment, and its windows are the input's
    plain = W.cut(rec.seq)
    assert plain.segments[-1] == 0
    off = W.cut(rec.seq, W.WindowParams(scan_match=ScanMatchParams(enabled=False)))
    np.testing.assert_array_equal(plain.bounds, off.bounds)
    # causal and chunk-free: a prefix has the same segments as the whole
    short = W.cut(seq.subset(np.arange(at + 40)))
    np.testing.assert_array_equal(short.segments, w.segments[: len(short.segments)])


def test_disabled_matching_is_the_input_odometry_and_bad_params_are_named():
    rec = _drifting(seed=4)
    p = W.WindowParams(scan_match=ScanMatchParams(enabled=False))
    w = W.cut(rec.seq, p)
    np.testing.assert_array_equal(w.odometry, rec.seq.odometry[w.keyframes])
    for bad in (dict(points=0), dict(gate=-1.0), dict(iters=2.5)):
        try:
            ScanMatchParams(**bad)
        except ValueError as e:
            assert next(iter(bad)) in str(e)
        else:
            raise AssertionError(f"accepted {bad}")


def test_thin_scan_drops_invalid_and_far_returns():
    p = dataclasses.replace(ScanMatchParams(), points=8, max_range=5.0)
    s = np.array([[1.0, 0.0], [np.nan, 1.0], [9.0, 0.0], [0.0, 2.0], [0.0, 2.01]])
    pts, mask = thin_scan(s, p)
    assert mask.sum() == 2  # the NaN and the 9 m return dropped, 2.0/2.01 share a voxel
    np.testing.assert_allclose(pts[mask], [[1.0, 0.0], [0.0, 2.0]], atol=1e-6)


def test_anchors_are_reported_in_the_input_odometry_frame():
    """The layer's anchors are of the refined odometry; the decisions file gives the anchor that
    places the robot from the input odometry, and both scorers agree on it."""
    import pandas as pd

    from mfcl_jax.robot import records
    from mfcl_jax.score import score_batch, score_decisions

    rec = _drifting(seed=5)
    w = W.cut(rec.seq, W.WindowParams())
    batch = W.pack([(rec.seq, w, 0)])
    Y = pose_at(rec.truth.times, rec.truth.poses, w.t)
    H = se2.compose_host(Y, se2.inverse_host(w.X))  # each window's right anchor, layer frame
    frame = pd.DataFrame(dict(run=0, k=np.arange(1, len(w) + 1), state="COMMIT", policy="ours",
                              x=H[:, 0], y=H[:, 1], yaw_deg=np.degrees(H[:, 2])))  # fmt: skip
    a = score_batch(frame, batch, [rec], rooms=False)
    assert a["err_xy"].max() < 1e-6

    def line(k, X_input=None):
        a = dict(x=H[k, 0], y=H[k, 1], yaw_deg=np.degrees(H[k, 2]))
        d = dict(k=k + 1, t=float(w.t[k]), state="COMMIT", symmetry=None, tau=None, B1=3,
                 B2=0, margin=3, anchor=a)  # fmt: skip
        return records.record(d, w.X[k], "", (0.0, 0.0), X_input)

    recs = [line(k, w.X_input[k]) for k in range(len(w))]
    np.testing.assert_allclose([r["pose"]["x"] for r in recs], Y[:, 0], atol=1e-6)
    b = score_decisions(recs, rec.seq.times, rec.seq.odometry, rec.truth.times, rec.truth.poses)
    assert b["err_xy"].max() < 1e-6 and b["err_yaw_deg"].max() < 1e-4
    # Without the conversion, the input odometry would place the robot off by the drift.
    raw = [line(k) for k in range(len(w))]
    c = score_decisions(raw, rec.seq.times, rec.seq.odometry, rec.truth.times, rec.truth.poses)
    assert c["err_xy"].max() > 0.05


def test_far_from_the_origin_the_poses_are_as_precise():
    """Odometry in a large frame (UTM-like, 100 km out) is refined as at the origin: the kernel
    works in float32 around the first keyframe."""
    rec = _drifting(seed=6)
    seq = rec.seq
    kf = W.keyframes(seq.odometry)[:80]
    raw = seq.odometry[kf]
    seg = np.zeros(len(kf), int)
    scans = [seq.scans[i] for i in kf]
    far = raw + np.array([1e5, -2e5, 0.0])
    a = scan_match(scans, raw, seg)
    b = scan_match(scans, far, seg) - np.array([1e5, -2e5, 0.0])
    np.testing.assert_allclose(b, a, atol=2e-3)


def test_along_a_bare_corridor_the_input_odometry_is_kept():
    """Two parallel walls and nothing else: the scans fix the heading (and with it the lateral
    offset), not the position along the corridor, which must follow the input odometry (a scan
    matcher that trusted its few off-square normals would slide or stick there)."""
    n = 60
    x = np.arange(n) * 0.25
    wall_x = np.arange(-20.0, 40.0, 0.05)
    scans = []
    for px in x:
        near = wall_x[np.abs(wall_x - px) < 8.0] - px
        scans.append(np.concatenate([np.stack([near, np.full_like(near, 1.5)], 1),
                                     np.stack([near, np.full_like(near, -1.5)], 1)]))  # fmt: skip
    # Wheel-like input: every 0.25 m step over-counted by 2 % and turned by a random 1 deg.
    rng = np.random.default_rng(0)
    inc = np.stack(
        [np.full(n - 1, 0.255), np.zeros(n - 1), np.deg2rad(rng.normal(0, 1.0, n - 1))], 1
    )
    odo = np.zeros((n, 3))
    for i in range(1, n):
        odo[i] = se2.compose_host(odo[i - 1], inc[i - 1])
    assert np.max(np.abs(np.degrees(odo[:, 2]))) > 3.0
    out = scan_match(scans, odo, np.zeros(n, int))
    # The heading and so the lateral offset are the scans' to fix ...
    assert np.max(np.abs(np.degrees(out[:, 2]))) < 0.5
    assert np.max(np.abs(out[:, 1])) < 0.05
    # ... the travel along the corridor is the input's (the scans cannot tell).
    travel = np.hypot(*np.diff(out[:, :2], axis=0).T).sum()
    assert abs(travel - 0.255 * (n - 1)) < 0.05  # without the degeneracy rule: 0.11-0.14 m short
