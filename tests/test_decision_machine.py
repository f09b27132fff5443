"""The commit machine: a commit persists, tracks, and ends only on contradicting evidence."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax.decision import machine
from mfcl_jax.decision.outcome import AMBIGUOUS, COMMIT, DEFER, REASONS, Decision
from mfcl_jax.decision.params import DecisionParams

P = DecisionParams().as_arrays()


@jax.jit
def _track(raw, H, score, mask, X, use_gate):
    """The machine over a sequence of windows (``machine.step`` per window, as the layer)."""

    def body(h, xs):
        d, *newest = xs
        return machine.step(h, d, newest, P, use_gate)

    return jax.lax.scan(body, machine.initial(), (raw, H, score, mask, X))[1]


def _raw(states, anchors):
    """A sequence of per-prefix decisions (only the fields the machine reads matter)."""
    k = len(states)
    z = jnp.zeros(k, jnp.float32)
    i = jnp.zeros(k, jnp.int32)
    return Decision(
        state=jnp.asarray(states, jnp.int32),
        kind=i,
        anchor=jnp.asarray(anchors, jnp.float32),
        tau=jnp.zeros((k, 2)),
        b1=i,
        b2=i,
        margin=i,
        n_groups=i,
        n_champions=i,
        spread=z,
        rooms=i,
        c_winner=jnp.ones(k, jnp.float32),
        winner_gate=jnp.zeros(k, bool),
        probe_alias=jnp.zeros(k, bool),
        probe_c=z,
        reason=i,
        max_score=z,
        alias_motion=jnp.zeros((k, 3)),
        competitor=jnp.zeros((k, 3)),
        has_competitor=jnp.zeros(k, bool),
        n_live=i,
        certified=jnp.zeros(k, bool),
        searched=jnp.zeros(k, bool),
        n_rejected=i,
        dropped=i,
        llr=z,
        test_anchor=jnp.zeros((k, 3)),
    )


def _run(states, anchors, c_winner=None):
    raw = _raw(states, anchors)
    if c_winner is not None:
        raw = dataclasses.replace(raw, c_winner=jnp.asarray(c_winner, jnp.float32))
    k = len(states)
    H, score, mask = jnp.zeros((k, 1, 3)), jnp.zeros((k, 1)), jnp.zeros((k, 1), bool)
    out = _track(raw, H, score, mask, jnp.zeros((k, 3)), jnp.bool_(True))
    return jax.tree.map(np.asarray, out)


A = np.array([10.0, 5.0, 0.3])
FAR = A + [7.3, 0.0, 0.0]


def test_commit_persists_through_a_late_ambiguity_and_tracks_drift():
    drift = [A + [0.05 * k, 0.0, 0.002 * k] for k in range(6)]
    states = [DEFER, COMMIT, AMBIGUOUS, AMBIGUOUS, DEFER, COMMIT]
    out = _run(states, drift)
    assert list(out.state) == [DEFER] + [COMMIT] * 5
    # the held anchor follows the per-prefix winner half-way each window: it moves toward
    # the drifting winner and lags it by about one window's drift
    d = np.asarray(drift)
    err = np.abs(out.anchor[1:] - d[1:])
    assert np.all(err[:, 0] <= 0.05 + 1e-5) and np.all(np.diff(out.anchor[1:, 0]) > 0)
    np.testing.assert_allclose(out.anchor[1], d[1], atol=1e-6)
    assert list(out.reason[1:]) == [0] * 5


def test_a_far_anchor_while_undecided_does_not_move_the_commit():
    states = [COMMIT, AMBIGUOUS, COMMIT]
    out = _run(states, [A, FAR, A])
    assert list(out.state) == [COMMIT] * 3
    np.testing.assert_allclose(out.anchor, np.stack([A, A, A]), atol=1e-6)


def test_a_decisive_other_anchor_contradicts_the_commit():
    out = _run([COMMIT, COMMIT, COMMIT, COMMIT], [A, A, FAR, FAR])
    assert list(out.state) == [COMMIT, COMMIT, AMBIGUOUS, COMMIT]
    assert REASONS[int(out.reason[2])] == "commit contradicted"
    # the two explanations listed: the new winner, and the commit it contradicts
    np.testing.assert_allclose(out.anchor[2], FAR, atol=1e-6)
    assert out.has_competitor[2] and not out.has_competitor[[0, 1, 3]].any()
    np.testing.assert_allclose(out.competitor[2], A, atol=1e-6)
    np.testing.assert_allclose(out.anchor[3], FAR, atol=1e-6)  # re-committed afterwards


def test_an_infeasible_commit_is_left_with_a_reason():
    out = _run([COMMIT, COMMIT, DEFER], [A, A, A], c_winner=[1.0, 0.1, 1.0])
    assert list(out.state) == [COMMIT, DEFER, DEFER]
    assert REASONS[int(out.reason[1])] == "commit infeasible"


def test_the_newest_window_candidate_tracks_a_held_anchor_without_champions():
    """After the commit the per-prefix winner may vanish (no champion); the newest window's
    candidate near the held anchor still carries the drift."""
    k = 4
    states = [COMMIT, DEFER, DEFER, DEFER]
    raw = _raw(states, [A, np.zeros(3), np.zeros(3), np.zeros(3)])
    drifted = np.stack([A + [0.1 * i, 0.0, 0.01 * i] for i in range(k)])
    H = jnp.asarray(drifted[:, None, :], jnp.float32)
    out = _track(raw, H, jnp.ones((k, 1)), jnp.ones((k, 1), bool), jnp.zeros((k, 3)),
                 jnp.bool_(True))  # fmt: skip
    out = jax.tree.map(np.asarray, out)
    assert list(out.state) == [COMMIT] * 4
    assert np.all(np.diff(out.anchor[:, 0]) > 0)  # it follows the drift...
    assert np.all(np.abs(out.anchor[:, 0] - drifted[:, 0]) <= 0.1 + 1e-5)  # one window behind


def test_noisy_registrations_do_not_walk_a_commit_off():
    """A hall pins one direction only: every window's candidates scatter along the other
    (sd 0.25 m) with scores that say nothing. While COMMIT is reported the tracked anchor must
    stay within the 1 m of a correct answer; the commit may end only as ``commit stale``, in a
    window whose best registration is beyond the tracking tolerance (0.5 m). The price of that
    rule shows here: with this scatter a commit is held a median of about 12 windows (at
    sd 0.6 m, 1-4), then the next windows decide afresh."""
    k, j = 60, 8
    worst, held = [], []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        H = np.broadcast_to(A, (k, j, 3)).copy()
        H[:, :, 1] += rng.normal(0.0, 0.25, (k, j))
        score = rng.uniform(0.5, 1.0, (k, j))
        raw = _raw([COMMIT] + [DEFER] * (k - 1), [A] + [np.zeros(3)] * (k - 1))
        h, s = jnp.asarray(H, jnp.float32), jnp.asarray(score, jnp.float32)
        ok = jnp.ones((k, j), bool)
        out = _track(raw, h, s, ok, jnp.zeros((k, 3)), jnp.bool_(True))
        state, anchor = np.asarray(out.state), np.asarray(out.anchor)
        n = int(np.argmin(state == COMMIT)) if (state != COMMIT).any() else k
        held.append(n)
        worst.append(np.max(np.abs(anchor[:n, 1] - A[1])))
        if n < k:  # left: stale, the best registration of that window beyond 0.5 m
            assert REASONS[int(out.reason[n])] == "commit stale"
            top = H[n, np.argmax(score[n])]
            assert abs(top[1] - anchor[n - 1, 1]) > machine.TRACK[0]
    assert max(worst) < 1.0, worst
    assert np.median(held) >= 6, held  # commits hold for windows: the tracking is exercised


def test_a_commit_the_newest_registration_leaves_behind_is_stale():
    """The odometry turns the true anchor faster than the half-way tracking follows (the raw
    Intel bag: 1.5-2 deg a window): once the newest window's best registration places the
    robot farther than 3 deg from the held anchor, at the same place, the commit ends
    (``DEFER``, ``commit stale``) instead of being reported wrong."""
    k = 5
    turn = [A + [0.0, 0.0, np.deg2rad(a)] for a in (0.0, 1.0, 2.0, 6.0, 6.5)]
    raw = _raw([COMMIT] + [DEFER] * (k - 1), [A] + [np.zeros(3)] * (k - 1))
    H = jnp.asarray(np.stack(turn)[:, None, :], jnp.float32)
    x = jnp.asarray(np.tile([3.0, 1.0, 0.2], (k, 1)), jnp.float32)
    out = _track(raw, H, jnp.ones((k, 1)), jnp.ones((k, 1), bool), x, jnp.bool_(True))
    out = jax.tree.map(np.asarray, out)
    assert list(out.state[:3]) == [COMMIT] * 3
    assert out.state[3] == DEFER and REASONS[int(out.reason[3])] == "commit stale"
    assert out.state[4] == DEFER  # the machine starts over; the per-prefix rule says DEFER
    # a registration elsewhere (an alias 7 m away) is not staleness: the commit holds
    far = np.stack(turn[:3] + [FAR, FAR])
    out = _track(raw, jnp.asarray(far[:, None, :], jnp.float32), jnp.ones((k, 1)),
                  jnp.ones((k, 1), bool), x, jnp.bool_(True))  # fmt: skip
    assert list(np.asarray(out.state)) == [COMMIT] * k


def test_a_commit_the_last_metre_does_not_support_is_left():
    """``leave_drifted``: a COMMIT lane with a verdict (drifted, unsupported) reports DEFER
    with it and holds no commit afterwards; a lane without one, or not committing, is
    unchanged."""
    states = [COMMIT, COMMIT, DEFER, COMMIT]
    raw = dataclasses.replace(_raw(states, [A] * 4), reason=jnp.asarray([0, 0, 4, 0], jnp.int32),
                              has_competitor=jnp.asarray([True, False, True, False]))  # fmt: skip
    held = machine.Held(jnp.asarray([True, True, False, False]), jnp.asarray([A] * 4, jnp.float32))
    verdict = jnp.asarray([machine.DRIFTED, 0, machine.UNSUPPORTED, machine.UNSUPPORTED])
    held2, out = jax.jit(machine.leave_drifted)(held, raw, verdict)
    assert list(np.asarray(out.state)) == [DEFER, COMMIT, DEFER, DEFER]
    reasons = [REASONS[int(r)] for r in np.asarray(out.reason)]
    assert reasons == ["commit drifted", "", "unsaturated", "commit unsupported"]
    assert list(np.asarray(held2.committed)) == [False, True, False, False]
    assert list(np.asarray(out.has_competitor)) == [False, False, True, False]
