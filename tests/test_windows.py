"""Windows (the one place submaps are cut) and the one scorer shared by every consumer."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mfcl_jax import windows as W
from mfcl_jax.io import read_decisions, write_decisions
from mfcl_jax.score import score_batch, score_decisions
from mfcl_jax.sources import Recording, ScanSequence
from mfcl_jax.sources.recording import GroundTruth
from mfcl_jax.windows import ScanMatchParams

# The line sequence's scans move with the sensor (not a rigid world), so the tests of the
# cutting itself use the input odometry as it is.
RAW = ScanMatchParams(enabled=False)


def _line_sequence(n=120, spacing=0.25, with_nan=False):
    """A straight walk along x past a wall at y = 2 (scans in the sensor frame)."""
    t = np.arange(n) * 0.5
    odo = np.stack([np.arange(n) * spacing, np.zeros(n), np.zeros(n)], 1)
    xs = np.linspace(-3, 3, 61)
    scans = []
    for i in range(n):
        s = np.stack([xs, np.full_like(xs, 2.0)], 1)
        if with_nan and i % 10 == 0:
            s[::7] = np.nan
        scans.append(s)
    return ScanSequence(t, scans, odo, "line")


def test_keyframes_windows_and_cut_are_consistent():
    seq = _line_sequence()
    w = W.cut(seq, W.WindowParams(d_s=6.0, step=2.0, scan_match=RAW))
    # 29.75 m straight: floor((29.75 - 6) / 2) + 1 = 12 windows.
    assert len(w) == 12
    np.testing.assert_array_equal(w.keyframes, np.arange(120))  # 0.25 m > 0.20 m spacing
    np.testing.assert_array_equal(w.last_scan(), w.bounds[:, 1])
    np.testing.assert_allclose(w.X, seq.odometry[w.bounds[:, 1]])
    np.testing.assert_allclose(w.t, seq.times[w.bounds[:, 1]])
    for pts, org in zip(w.points, w.origins, strict=True):
        assert np.all(np.isfinite(pts)) and pts.shape == org.shape
        # every point is on the wall y = 2 in the frame of the window's last scan
        np.testing.assert_allclose(pts[:, 1], 2.0, atol=1e-9)
        assert np.all(np.linalg.norm(pts, axis=1) <= 10.0 + 1e-9)  # cropped at 10 m


def test_cut_is_causal_prefix_of_a_longer_sequence():
    long = _line_sequence(120)
    short = long.subset(np.arange(80))
    a, b = W.cut(long), W.cut(short)
    assert 0 < len(b) < len(a)
    np.testing.assert_array_equal(a.bounds[: len(b)], b.bounds)
    for p, q in zip(a.points[: len(b)], b.points, strict=True):
        np.testing.assert_array_equal(p, q)


def test_rethinning_when_over_capacity_and_error_beyond():
    seq = _line_sequence()
    dense = W.cut(seq, W.WindowParams(voxel=0.02, capacity=128))
    assert np.all(W.rethinned(dense)) and all(len(p) <= 128 for p in dense.points)
    with pytest.raises(Exception, match="over the capacity"):
        W.cut(seq, W.WindowParams(voxel=0.001, capacity=64, max_rethin=0))


def test_pack_and_concat_index_runs_and_submaps():
    seq = _line_sequence()
    wa, wb = W.cut(seq, W.WindowParams(d_s=6.0)), W.cut(seq, W.WindowParams(d_s=10.0))
    a = W.pack([(seq, wa, 0)])
    b = W.pack([(seq, wb, 1)])
    both = W.pack([(seq, wa, 0), (seq, wb, 1)])
    cat = W.concat([a, b])
    assert cat.submaps.n == both.submaps.n == len(wa) + len(wb)
    np.testing.assert_array_equal(cat.runs.submap, both.runs.submap)
    np.testing.assert_array_equal(cat.submaps.run, both.submaps.run)
    np.testing.assert_array_equal(cat.building, [0] * len(wa) + [1] * len(wb))
    np.testing.assert_allclose(cat.submaps.X, both.submaps.X)
    assert cat.submaps.points.shape[1] == 0  # concat keeps no points
    np.testing.assert_array_equal(cat.evidence.end_mask, both.evidence.end_mask)
    # the end sample: the window's last scan alone, in its own frame (the submap's), as many
    # points as it has up to EVIDENCE_POINTS
    for k, j1 in enumerate(wa.bounds[:, 1]):
        scan = np.asarray(seq.scans[wa.keyframes[j1]], np.float32).reshape(-1, 2)
        scan = scan[
            np.all(np.isfinite(scan), axis=1) & (np.hypot(*scan.T) <= wa.params.crop_radius)
        ]
        m = a.evidence.end_mask[k]
        assert 0 < m.sum() == min(len(scan), W.EVIDENCE_POINTS)
        got = a.evidence.end_points[k][m].view(np.complex64)
        assert np.isin(got, scan.view(np.complex64)).all()
        np.testing.assert_array_equal(wa.last_points[k], scan)


def test_the_one_scorer_gives_one_verdict_for_every_consumer(tmp_path):
    """Study/benchmark (``score_batch`` on a decision table) and ``mfcl evaluate`` (a JSON-lines
    log) score the same decisions identically."""
    seq = _line_sequence()
    anchor = np.array([3.0, -1.0, 0.3])
    c, s = np.cos(anchor[2]), np.sin(anchor[2])
    R = np.array([[c, -s], [s, c]])
    true = np.concatenate(
        [seq.odometry[:, :2] @ R.T + anchor[:2], (seq.odometry[:, 2:] + anchor[2])], 1
    )
    rec = Recording("line", None, seq, GroundTruth(seq.times, true))
    w = W.cut(seq, W.WindowParams(scan_match=RAW))
    batch = W.pack([(seq, w, 0)])
    import pandas as pd

    rows = []
    offsets = [(0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (1.5, 0.0, 0.0), (0.0, 0.0, 6.0)]
    for k in range(1, len(w) + 1):
        dx, dy, dyaw = offsets[k % len(offsets)]
        rows.append(
            dict(run=0, k=k, state="COMMIT", policy="ours", x=anchor[0] + dx,
                 y=anchor[1] + dy, yaw_deg=np.rad2deg(anchor[2]) + dyaw)
        )  # fmt: skip
    frame = pd.DataFrame(rows)
    a = score_batch(frame, batch, [rec], rooms=False)
    decisions = [
        dict(k=int(r.k), t=float(w.t[r.k - 1]), state="COMMIT", symmetry=None, tau=None,
             anchor=dict(x=r.x, y=r.y, yaw_deg=r.yaw_deg), B1=3, B2=0, margin=3)
        for r in frame.itertuples()
    ]  # fmt: skip
    write_decisions(tmp_path / "d.jsonl", decisions)
    b = score_decisions(read_decisions(tmp_path / "d.jsonl"), seq.times, seq.odometry,
                        seq.times, true)  # fmt: skip
    np.testing.assert_array_equal(a["correct"].to_numpy(), b["correct"].to_numpy())
    np.testing.assert_allclose(a["err_xy"], b["err_xy"], atol=1e-9)
    # 0 and 0.5 m are right, 1.5 m and 6 deg are wrong.
    expect = [o[0] < 1.0 and o[2] < 5.0 for o in (offsets[k % 4] for k in range(1, len(w) + 1))]
    assert list(a["correct"]) == expect
    assert json.loads((tmp_path / "d.jsonl").read_text().splitlines()[0])["state"] == "COMMIT"


def _restarted(seq, at):
    """``seq`` with its odometry re-zeroed at scan ``at`` (an odometry restart)."""
    odo = seq.odometry.copy()
    odo[at:] -= odo[at]
    return ScanSequence(seq.times, seq.scans, odo, "restarted")


def test_an_odometry_restart_splits_the_windows_and_nothing_else_does():
    seq = _line_sequence(120)
    assert W.odometry_segments(seq.odometry, seq.times)[-1] == 0
    jumped = _restarted(seq, 60)  # 15 m from the origin: a jump no robot makes in 0.5 s
    seg = W.odometry_segments(jumped.odometry, jumped.times)
    np.testing.assert_array_equal(seg, np.repeat([0, 1], 60))
    w = W.cut(jumped)
    np.testing.assert_array_equal(w.segments, seg[w.keyframes])
    first = w.keyframes[w.bounds]
    assert np.all(seg[first[:, 0]] == seg[first[:, 1]])  # no window straddles the jump
    # each half is cut as a sequence of its own: 14.75 m holds floor((14.75 - 6) / 2) + 1 = 5
    assert list(np.bincount(seg[first[:, 0]])) == [5, 5]
    # still causal: a prefix cut gives the first windows of the whole
    short = W.cut(jumped.subset(np.arange(90)))
    np.testing.assert_array_equal(w.bounds[: len(short)], short.bounds)
    # a fast but possible step (1 m in 0.5 s) is not a jump
    odo = seq.odometry.copy()
    odo[60:, 0] += 0.75
    assert W.odometry_segments(odo, seq.times)[-1] == 0


def test_run_inputs_start_the_layer_over_at_an_odometry_jump():
    """``decision.runs.run_inputs``: the first window of each odometry segment restarts the
    layer, its keyframe indices count from the segment's start, and its keyframes before the
    last ``step`` go to ``head`` (an empty history extends no walk)."""
    from types import SimpleNamespace

    from mfcl_jax.decision.inputs import run_inputs
    from mfcl_jax.frontend.candidates import Candidates

    K, T, J, P = 6, 24, 2, 4
    traj = np.zeros((1, T, 3), np.float32)
    traj[0, :, 0] = np.arange(T) * 0.25
    seg = np.zeros((1, T), np.int32)
    seg[0, 12:] = 1  # a restart at sample 12
    start = np.array([[0, 3, 6, 12, 15, 18]], np.int32)
    runs = SimpleNamespace(
        traj=traj,
        traj_seg=seg,
        traj_mask=np.ones((1, T), bool),
        window_start=start,
        window_end=start + 5,
        window_mask=np.ones((1, K), bool),
        submap=np.arange(K)[None],
    )
    sub = SimpleNamespace(n=K, X=np.zeros((K, 3), np.float32))
    ev = W.Evidence(  # no end sample: the layer's drift check is off
        points=np.zeros((K, P, 2), np.float32),
        origins=np.zeros((K, P, 2), np.float32),
        mask=np.ones((K, P), bool),
    )
    batch = SimpleNamespace(runs=runs, submaps=sub, evidence=ev)
    cands = Candidates(np.zeros((K, J, 3), np.float32), np.ones((K, J), np.float32),
                       np.ones((K, J), bool), np.zeros(K, np.int32))  # fmt: skip
    e = run_inputs(batch, cands, min_step=4).evidence
    assert e.restart[0].tolist() == [True, False, False, True, False, False]
    np.testing.assert_array_equal(e.start[0], [0, 3, 6, 0, 3, 6])

    # window 0 brings samples 0..5; window 1 the 3 after (6..8); window 3 samples 12..17
    def got(k):
        return np.concatenate([e.head[0, k][e.head_mask[0, k]], e.traj[0, k][e.traj_mask[0, k]]])

    np.testing.assert_array_equal(got(0)[:, 0], traj[0, 0:6, 0])
    np.testing.assert_array_equal(got(1)[:, 0], traj[0, 6:9, 0])
    np.testing.assert_array_equal(got(3)[:, 0], traj[0, 12:18, 0])
    assert e.traj_mask.shape[2] == 16 and e.last[0].tolist() == [False] * 5 + [True]
