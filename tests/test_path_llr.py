"""The path's log-likelihood (``frontend.path_llr``): evidence counted once per scan and per
metre, the truth explaining the path better than a shifted or turned placement, and a copy of
the building explaining it as well as the truth."""

import jax
import numpy as np
import pytest

from mfcl_jax import se2
from mfcl_jax.decision import drift, rivals
from mfcl_jax.decision import uniqueness as U
from mfcl_jax.frontend import path_llr
from mfcl_jax.sim.synthetic import PITCH, evidence_at, row_of_rooms, walk

# the kernels jitted once (run op by op they compile each operation per shape: hundreds)
evidence = jax.jit(path_llr.path_evidence)
loglik = jax.jit(path_llr.log_likelihood)
refine = jax.jit(path_llr.refine, static_argnames="steps")
edge = jax.jit(U.edge)
verdict = jax.jit(drift.verdict)


@pytest.fixture(scope="module")
def scene():
    fp = row_of_rooms(widths=(PITCH, 9.0, 5.5))  # rooms of different lengths
    fields = rivals.rival_fields(fp)
    traj = walk([[1.5, 1.5], [6.0, 1.5], [6.0, 3.5], [11.0, 2.5]])
    ks = np.linspace(0, len(traj) - 1, 8).round().astype(int)
    pts, org, msk = evidence_at(fp, traj[ks])
    return fp, fields, traj, ks, pts, org, msk


def _evidence(scene, windows):
    fp, fields, traj, ks, pts, org, msk = scene
    # one "window" per scan here; the odometry frame is the plan frame (anchor = identity)
    X = traj[ks][windows]
    length = float(np.sum(np.hypot(*np.diff(traj[:, :2], axis=0).T)))
    return evidence(pts[windows], org[windows], msk[windows], X, length)


def test_a_scan_seen_by_two_windows_counts_once(scene):
    once = _evidence(scene, [0, 1, 2, 3])
    twice = _evidence(scene, [0, 1, 1, 2, 3])  # window 1's scan again, as overlapping windows do
    assert int(once.n_scans) == int(twice.n_scans) == 4
    np.testing.assert_allclose(float(np.sum(twice.pw)), float(np.sum(once.pw)), rtol=1e-5)
    # each scan's returns weigh metres-per-scan in all (one observation per metre)
    np.testing.assert_allclose(float(np.sum(once.pw)), float(once.length), rtol=1e-5)


def test_the_true_placement_explains_the_path_best(scene):
    fields = scene[1]
    pe = _evidence(scene, list(range(8)))
    truth = np.zeros(3, np.float32)
    L0 = float(loglik(truth, pe, fields))
    for wrong in ([0.6, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, np.radians(4.0)]):
        Lw = float(loglik(np.asarray(wrong, np.float32), pe, fields))
        assert L0 - Lw > 3.0, (wrong, L0, Lw)
    a, L = refine(np.asarray([0.08, -0.05, 0.01], np.float32), pe, fields)
    assert float(L) >= L0 - 1e-3 and np.hypot(*np.asarray(a)[:2]) < 0.05


def test_a_congruent_copy_explains_a_walk_inside_one_room_as_well_as_the_truth():
    fp = row_of_rooms()  # four congruent rooms at PITCH, doors at the same place
    fields = rivals.rival_fields(fp)
    traj = walk([[2.0, 1.2], [5.0, 1.2], [5.0, 4.0]])  # stays inside room 2 of 4 (x 7.3 - 14.6)
    traj[:, 0] += PITCH
    ks = np.linspace(0, len(traj) - 1, 6).round().astype(int)
    pts, org, msk = evidence_at(fp, traj[ks])
    length = float(np.sum(np.hypot(*np.diff(traj[:, :2], axis=0).T)))
    pe = evidence(pts, org, msk, traj[ks], length)
    L0 = float(loglik(np.zeros(3, np.float32), pe, fields))
    shifted = se2.compose_host(np.asarray([PITCH, 0.0, 0.0]), np.zeros(3))
    L1 = float(loglik(np.asarray(shifted, np.float32), pe, fields))
    assert abs(L0 - L1) < 0.5, (L0, L1)


def test_the_uniqueness_lanes_fit_reaches_a_peak_past_the_fits_own_rounds(scene):
    """The lanes fit with a first round of 0.3 m / 3 deg (``UniqueParams.polish``): from a
    placement 0.45 m, 0.3 m and 4 deg off the truth it reaches the truth, which the fit's own
    rounds (at most 0.175 m and 1.75 deg from where they start) cannot (the path's peak lies
    4-5 cm from the truth here: the evidence's rays end on the plan's raster)."""
    fields = scene[1]
    pe = _evidence(scene, list(range(8)))
    L0 = float(loglik(np.zeros(3, np.float32), pe, fields))
    start = np.asarray([0.45, -0.3, np.radians(4.0)], np.float32)
    a, L = refine(start, pe, fields, steps=U.DEFAULT_UNIQUE.polish)
    assert float(L) >= L0 - 1e-3 and np.hypot(*np.asarray(a)[:2]) < 0.08, (a, L, L0)
    a_own, L_own = refine(start, pe, fields)
    assert np.hypot(*np.asarray(a_own)[:2]) > 0.2 and float(L_own) < L0 - 1.0, (a_own, L_own)


def test_the_uniqueness_tests_edge_is_the_best_placement_just_past_its_line(scene):
    """On a short path the peak is wider than the line a commit is judged by (1 m, 5 deg
    where the robot is): a placement just past it, on the same peak, climbs back into the
    best one when fitted freely, so ``uniqueness.edge`` fits placements that stay outside.
    Its score is at least that of every placement of a dense ring just past the line."""
    u = U.DEFAULT_UNIQUE
    fields = scene[1]
    windows = [0, 1, 2]
    pe = _evidence(scene, windows)
    x_now = np.asarray(scene[2][scene[3]][windows[-1]], np.float32)
    best, L_best = refine(np.zeros(3, np.float32), pe, fields, steps=u.polish)
    e, L_e = edge(best, x_now, pe, fields)
    now = se2.compose_host(np.asarray(best), x_now)

    def judged(a):  # where the placement puts the robot, against A* (host arithmetic)
        d = se2.compose_host(np.asarray(a), x_now) - now
        return np.hypot(d[..., 0], d[..., 1]), np.abs(np.degrees(np.angle(np.exp(1j * d[..., 2]))))

    dxy, dth = judged(e)
    assert dxy > 1.0 or dth > 5.0, (dxy, dth)
    # within log(1 / alpha) of the best at alpha = 1e-2: the lane waits for a longer path
    assert 0.0 < float(L_best) - float(L_e) < np.log(1e2), (float(L_best), float(L_e))
    # a dense ring just past the line: moved 1.0-1.3 m, or turned 5-8 deg about points of
    # the path, each with small turns and shifts of its own
    rng = np.random.default_rng(0)
    n = 4000
    phi, r = rng.uniform(0, 2 * np.pi, n), rng.uniform(1.01, 1.3, n)
    moved = now + np.stack([r * np.cos(phi), r * np.sin(phi), np.radians(rng.uniform(-4, 4, n))], 1)
    th = np.radians(rng.uniform(5.05, 8.0, n)) * rng.choice([-1, 1], n)
    q = now[:2] + rng.uniform(-8, 8, (n, 2))
    c, s_ = np.cos(th)[:, None], np.sin(th)[:, None]
    v = now[:2] - q
    turned_xy = q + np.concatenate([c * v[:, :1] - s_ * v[:, 1:], s_ * v[:, :1] + c * v[:, 1:]], 1)
    turned = np.concatenate([turned_xy, (now[2] + th)[:, None]], 1)
    ring = se2.compose_host(np.concatenate([moved, turned]), se2.inverse_host(x_now))
    sxy, sth = judged(ring)
    ring = ring[(sxy > 1.0) | (sth > 5.0)].astype(np.float32)
    L_ring = np.asarray(jax.jit(jax.vmap(loglik, in_axes=(0, None, None)))(ring, pe, fields))
    assert float(L_e) >= L_ring.max() - 0.05, (float(L_e), L_ring.max(), float(L_best))
    # why it is searched apart: the best of the ring, fitted freely, ends inside the line
    a, _ = refine(ring[np.argmax(L_ring)], pe, fields, steps=u.polish)
    fxy, fth = judged(a)
    assert fxy <= 1.0 and fth <= 5.0, (fxy, fth)


def test_the_uniqueness_fit_fits_the_admissible_candidates_only_block_by_block(scene):
    """``uniqueness.fit`` packs the admissible candidates first and fits them in blocks
    (here of 3, so 7 admissible ones take three blocks): each gets the fit it would get alone,
    the inadmissible ones keep their placement and ``L = -inf``."""
    from dataclasses import replace

    u = replace(U.DEFAULT_UNIQUE, fit_block=3)
    fields = scene[1]
    pe = _evidence(scene, list(range(8)))
    rng = np.random.default_rng(1)
    cand = (rng.uniform(-1, 1, (10, 3)) * [0.6, 0.6, 0.1]).astype(np.float32)
    ok = np.array([1, 0, 1, 1, 0, 1, 1, 0, 1, 1], bool)
    A, L = jax.jit(U.fit, static_argnames="u")(cand, ok, pe, fields, u=u)
    A, L = np.asarray(A), np.asarray(L)
    assert np.all(np.isneginf(L[~ok])) and np.array_equal(A[~ok], cand[~ok])
    one = jax.jit(jax.vmap(lambda a: path_llr.refine(a, pe, fields, u.llr, u.polish)))
    A1, L1 = (np.asarray(x) for x in one(cand[ok]))
    np.testing.assert_allclose(L[ok], L1, atol=1e-4)
    np.testing.assert_allclose(A[ok], A1, atol=1e-5)
    assert np.all(L[ok] > -np.inf) and not np.allclose(A[ok], cand[ok])


def test_the_last_metre_tells_a_turned_pose_from_a_right_one(scene):
    """A commit's pose 5-6 deg off the truth has drifted (the scans' fit turns back past the
    3 deg tolerance), one 1.5 deg off or a few cm off has not; placed where its scans touch
    no wall it is unsupported; too few points: no verdict."""
    fp, fields, traj, ks, pts, org, msk = scene
    D, U = drift.DRIFTED, drift.UNSUPPORTED
    for i in range(0, len(ks), 2):
        truth = traj[ks[i]]
        for deg, want in ((0.0, 0), (1.5, 0), (-1.5, 0), (5.0, D), (-6.0, D)):
            pose = truth + np.array([0.06, -0.04, np.radians(deg)])
            assert int(verdict(pose, pts[i], msk[i], fields)) == want, (i, deg)
        outside = truth + np.array([0.0, 40.0, 0.0])  # the plan's walls far away
        assert int(verdict(outside, pts[i], msk[i], fields)) == U
    few = msk[0] & (np.cumsum(msk[0]) < drift.MIN_POINTS)
    assert int(verdict(traj[ks[0]] + np.array([0.0, 0.0, np.radians(6.0)]), pts[0], few,
                       fields)) == 0  # fmt: skip
