"""Anchors, feasibility gate, grouping and lattice kernels of the decision layer."""

import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from mfcl_jax import se2
from mfcl_jax.decision import gate, lattice
from mfcl_jax.decision.anchors import candidate_anchors, sanitize
from mfcl_jax.decision.consensus import leader_groups
from mfcl_jax.decision.maps import decision_maps
from mfcl_jax.sim.synthetic import PITCH, row_of_rooms, three_rooms, walk

ROW = jax.tree.map(jnp.asarray, decision_maps(row_of_rooms()))
CLOSED = jax.tree.map(jnp.asarray, decision_maps(row_of_rooms(closed=(2,))))


@jax.jit
def _consistency(maps, H, traj, valid):
    walk = gate.extend_walk(maps, H, traj, valid, gate.start_walk(H.shape[:-1]))
    return walk.consistency()


def _c(maps, H, traj, cap=256):
    # One padded trajectory length, so every call reuses one compilation.
    n = len(traj)
    tr = np.zeros((cap, 3), np.float32)
    tr[:n] = traj
    H = np.asarray(H, np.float32)
    return float(_consistency(maps, H, tr, np.arange(cap) < n))


pose = st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-3.1, 3.1)).map(
    lambda t: np.asarray(t, np.float32)
)


@given(pose, pose, pose)
def test_anchor_is_Y_Xinv_and_maps_submap_to_floorplan(a, x, y):
    # The true anchor A with Y = A X must be recovered; X^-1 Y differs once X rotates.
    Y = np.asarray(se2.compose(a, x))
    H = np.asarray(candidate_anchors(Y[None, None], x[None]))[0, 0]
    dxy, dth = se2.distance_pair(H, a)
    assert float(dxy) < 1e-3 and float(dth) < 1e-4


def test_anchor_order_matters():
    a = np.array([5.0, -2.0, 0.3], np.float32)
    x = np.array([1.0, 4.0, 1.2], np.float32)
    Y = np.asarray(se2.compose(a, x))
    wrong = np.asarray(se2.compose(se2.inverse(x), Y))  # X^-1 Y
    assert float(se2.distance_pair(wrong, a)[0]) > 1.0
    H = np.asarray(candidate_anchors(Y[None, None], x[None]))[0, 0]
    assert float(se2.distance_pair(H, a)[0]) < 1e-4


def test_sanitize_masks_and_counts_non_finite():
    p = np.zeros((2, 3, 3), np.float32)
    p[0, 1, 2] = np.nan
    s = np.ones((2, 3), np.float32)
    s[1, 2] = np.inf
    m = np.ones((2, 3), bool)
    m[1, 0] = False
    p2, s2, m2, bad = sanitize(p, s, m)
    assert np.all(np.isfinite(p2)) and np.all(np.isfinite(s2))
    assert np.asarray(bad).tolist() == [1, 1]
    assert np.asarray(m2).tolist() == [[True, False, True], [False, True, False]]


def test_gate_passes_legal_revisit():
    # 1 -> 2 -> 3 -> 2 -> 1 through the doors (the 209-208-207-208-209 pattern).
    tr = walk([[10, 2.5], [17, 2.5], [25, 2.5], [17, 2.5], [10, 2.5]])
    assert _c(ROW, [0, 0, 0], tr) > 0.95


def test_gate_fails_jump_between_non_adjacent_rooms_and_leaving_the_building():
    tr = walk([[10, 2.5], [17, 2.5]])
    assert _c(CLOSED, [0, 0, 0], tr) < 0.5  # wall 2 has no door: r1 -> r2 is not an edge
    assert _c(ROW, [0, 0, 0], tr) > 0.95
    # Shifted two pitches to the right the second room lies outside the building.
    tr2 = walk([[10, 2.5], [17, 2.5], [10, 2.5]])
    assert _c(ROW, [2 * PITCH, 0, 0], tr2) < 0.5


def test_a_walk_extended_piece_by_piece_equals_one_walk_over_all_samples():
    """The layer extends each candidate's walk by the keyframes a window adds; the counts
    must be the integers of one walk over the whole trajectory, however it is cut."""
    rng = np.random.default_rng(0)
    tr = walk([[3, 2.5], [25, 2.5], [20, 4.0]]).astype(np.float32)
    H = np.concatenate([rng.uniform(-8, 8, (4, 5, 2)), rng.uniform(-0.5, 0.5, (4, 5, 1))], -1)
    H = H.astype(np.float32)
    valid = rng.random(len(tr)) > 0.1
    whole = gate.extend_walk(ROW, H, tr, valid, gate.start_walk(H.shape[:-1]))
    cuts = [0, 1, 20, 21, 60, len(tr)]
    w = gate.start_walk(H.shape[:-1])
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        w = gate.extend_walk(ROW, H, tr[a:b], valid[a:b], w)
    np.testing.assert_array_equal(np.asarray(w.counts), np.asarray(whole.counts))
    np.testing.assert_array_equal(np.asarray(w.prev), np.asarray(whole.prev))
    c = np.asarray(whole.consistency())
    assert c.min() >= 0 and c.max() <= 1


def test_congruent_room_offsets():
    m = jax.tree.map(lambda a: a[0], decision_maps(row_of_rooms()).sym)
    offs = m.offsets[m.offsets_mask]
    assert np.allclose(
        sorted(np.abs(offs[:, 0])),
        sorted([PITCH, PITCH, 2 * PITCH, 2 * PITCH, 3 * PITCH, 3 * PITCH]),
        atol=0.15,
    )
    assert np.allclose(m.generators[m.generators_mask], [[PITCH, 0]], atol=0.15)
    m3 = decision_maps(three_rooms()).sym
    assert not m3.offsets_mask.any() and not m3.generators_mask.any()


def test_leader_clustering_does_not_chain():
    # A chain with 1.0 m steps: single linkage would merge all; leaders split it.
    p = np.stack([np.arange(6.0), np.zeros(6), np.zeros(6)], -1).astype(np.float32)
    w = np.array([6, 5, 4, 3, 2, 1], np.float32)
    assign, _, ng = leader_groups(p, w, np.ones(6, bool), 1.5, 0.3)
    assert int(ng) == 3 and np.asarray(assign).tolist() == [0, 0, 1, 1, 2, 2]
    # Yaw beyond delta_theta opens a new group even at the same position.
    q = np.array([[0, 0, 0], [0, 0, 0.5]], np.float32)
    assert (
        int(leader_groups(q, np.array([2.0, 1.0], np.float32), np.ones(2, bool), 1.5, 0.3)[2]) == 2
    )


def _detect(anchors, maps=ROW, eps_t=2.5):
    a = np.asarray(anchors, np.float32)
    return lattice.detect(
        a,
        np.ones(len(a), bool),
        jnp.int32(0),
        maps.sym.offsets[0],
        maps.sym.offsets_mask[0],
        eps_t,
        np.deg2rad(12.0),
    )


def test_lattice_detects_fundamental_and_rejects_subharmonics():
    ok, tau = _detect([[0, 0, 0.1], [PITCH, 0.2, 0.1], [2 * PITCH, -0.1, 0.12]])
    assert bool(ok) and abs(float(tau[0]) - PITCH) < 0.3
    ok, tau = _detect([[0, 0, 0.1], [-2 * PITCH, 0, 0.1]])  # only 2p seen: p is a room offset
    assert bool(ok) and abs(float(tau[0]) - PITCH) < 0.3
    ok, _ = _detect([[0, 0, 0.1], [PITCH / 2, 0, 0.1]])  # half pitch is no room offset
    assert not bool(ok)
    ok, _ = _detect([[0, 0, 0.1], [PITCH, 0, 0.8]])  # yaw differs: no translation lattice
    assert not bool(ok)
    ok, _ = _detect([[0, 0, 0.1], [PITCH, 0, 0.1], [4.0, 3.0, 0.1]])  # incoherent third group
    assert not bool(ok)


def test_compact_lattice_test_equals_the_full_one_for_any_contender_mask():
    """``detect_from`` reads only the contenders' generators (``SLOTS`` of them at most, in
    index order), and every generator where more contend: the verdict and period are those of
    the full test for every mask, over a batch that mixes both (``vmap``: the full form runs in
    the rows with more contenders only)."""
    rng = np.random.default_rng(3)
    g = 16
    k = rng.integers(-3, 4, g).astype(np.float32)
    k[:9], k[10] = 0, 1  # eight groups beside the winner: no period among their generators
    anchors = np.stack([k * PITCH + rng.normal(0, 0.3, g), rng.normal(0, 0.3, g),
                        0.1 + rng.normal(0, 0.03, g)], -1).astype(np.float32)  # fmt: skip
    anchors[[11, 12]] = [[4.0, 3.0, 0.1], [PITCH / 2, 0.0, 0.1]]  # off the lattice
    offsets, omask = ROW.sym.offsets[0], ROW.sym.offsets_mask[0]
    fit = lattice.prepare(jnp.asarray(anchors), jnp.int32(0), offsets, 2.5)
    masks = rng.random((64, g)) < rng.uniform(0.05, 0.95, (64, 1))
    masks[:, 0] = True  # the winner
    masks[:8, [11, 12]] = False  # some coherent masks of many contenders
    masks[8] = np.isin(np.arange(g), [0, *range(1, 9), 10])  # the period only from the ninth
    n_others = masks[:, 1:].sum(1)
    assert (n_others > lattice.SLOTS).sum() >= 8 and (n_others <= lattice.SLOTS).sum() >= 8

    def both(m):
        ops = (fit, m, jnp.int32(0), offsets, omask, 2.5, np.deg2rad(12.0))
        return lattice.detect_from(*ops), lattice._full(3)(ops)

    (ok, tau), (ok_full, tau_full) = jax.jit(jax.vmap(both))(jnp.asarray(masks))
    assert np.asarray(ok).tolist() == np.asarray(ok_full).tolist()
    assert np.asarray(ok).any() and not np.asarray(ok).all() and bool(ok[8])
    np.testing.assert_allclose(np.asarray(tau), np.asarray(tau_full), atol=1e-5)
