"""Decision layer end to end: states, C2 immunity, invariances, lattice/probe, robot == batch.

All evaluations share one padded shape bucket so the jitted layer compiles once per lane set.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mfcl_jax import se2
from mfcl_jax.decision import REASONS, DecisionParams, layer, sanitize, to_frame
from mfcl_jax.decision.runs import TRACES
from tests._layer import (
    CAPS,
    J,
    K,
    T,
    evaluate_runs,
    evidence_of,
    lanes_of,
    maps_of,
    step,
    stepwise,
    window,
)
from tests.test_decision_scenes import PITCH, make_run, row_of_rooms, shift, three_rooms, walk

A = np.array([1.0, -2.0, 0.4])  # hidden ^B T_L
# r1 -> r2 -> r1 -> r0 -> r3: the shifted aliases die only once both row ends are visited.
PATH = [[10, 2.5], [18, 2.5], [10, 2.5], [3, 2.5], [26, 2.5]]
ROW = maps_of(row_of_rooms())


def run_all(runs, maps=ROW, params=None):
    out, names = evaluate_runs(runs, maps, params)
    return out


NAMES = lanes_of()[2].names
OURS = NAMES.index("ours")


def lattice_cands(k, Y):
    # true and +p alias alternate as champion; a low-scored stray candidate.
    return [(Y, 1.0), (shift(Y, PITCH), 1.05 if k % 2 else 0.9), (shift(Y, 2.0, 1.0), 0.3)]


def probe_cands(k, Y):
    # the true anchor always wins; the +p image is never a champion (tie-broken away).
    return [(Y, 1.0 + 0.01 * k), (shift(Y, PITCH), 0.9), (shift(Y, -3.0, 0.5), 0.2)]


ROW_FP = row_of_rooms()


def run_of(cand_fn, path=PATH, anchor=A, fp=ROW_FP):
    return make_run(walk(path), anchor, K, cand_fn, J=J, fp=fp)


def ours(out, k=None):
    d = jax.tree.map(lambda x: x[0, :, OURS], out)
    return d if k is None else jax.tree.map(lambda x: x[k], d)


def test_lattice_ambiguous_then_commit_when_aliases_become_infeasible():
    out = run_all([run_of(lattice_cands)])
    d = ours(out)
    states = d.state.tolist()
    amb = [k for k in range(K) if states[k] == 1 and d.kind[k] == 1]
    assert amb, states
    for k in amb:
        assert abs(np.linalg.norm(d.tau[k]) - PITCH) < 2.5
        # the listed competitor is the tied group a period away from T*
        assert d.has_competitor[k]
        gap = np.asarray(d.competitor[k][:2]) - np.asarray(d.anchor[k][:2])
        assert abs(np.linalg.norm(gap) - PITCH) < 2.5, (k, gap)
    assert states[-1] == 2  # the walk spans the whole row: every shifted anchor leaves the plan
    dxy, dth = se2.distance_pair(d.anchor[-1], A)
    assert float(dxy) < 0.05 and float(dth) < 1e-3


def test_probe_blocks_commit_while_alias_is_feasible():
    """The +pitch image is never a champion. The paper's probe blocks it while the gate admits
    it; ours blocks it while the scans cannot rule it out (AMBIGUOUS translation, period =
    pitch, reason "competitor not ruled out"), and commits once a window sees the end wall
    that the alias would put in the wrong place, no later than the paper's probe."""
    out = run_all([run_of(probe_cands)])
    idx = {n: i for i, n in enumerate(NAMES)}
    by = {n: jax.tree.map(lambda x, i=i: x[0, :, i], out) for n, i in idx.items()}
    d, paper, no_probe = by["ours"], by["paper"], by["no_probe"]
    blocked = [k for k in range(K) if paper.state[k] == 1 and paper.probe_alias[k]]
    assert blocked and all(paper.kind[k] == 1 for k in blocked), paper.state.tolist()
    assert all(no_probe.state[k] == 2 for k in blocked if paper.b1[k] >= 3)
    assert abs(float(paper.tau[blocked[0]][0]) - PITCH) < 0.3
    held = [k for k in range(K) if d.state[k] == 1 and d.kind[k] == 1]
    assert held and all(REASONS[int(d.reason[k])] == "competitor not ruled out" for k in held)
    assert all(abs(float(d.tau[k][0]) - PITCH) < 0.3 for k in held)
    # the competing explanation is listed: the +pitch image of T*, the one not ruled out
    for k in held:
        assert d.has_competitor[k]
        g = se2.compose(d.competitor[k], se2.inverse(d.anchor[k]))
        assert abs(float(g[0]) - PITCH) < 0.3 and abs(float(g[1])) < 0.3, (k, g)
    assert not d.has_competitor[-1]  # a COMMIT lists none
    assert d.state[-1] == 2 and paper.state[-1] == 2
    first = lambda s: int(np.argmax(np.asarray(s) == 2))  # noqa: E731
    assert first(d.state) <= first(paper.state)


def test_defer_without_anchors_below_floor_and_unsaturated():
    empty = run_of(lambda k, Y: [])
    low = run_of(lambda k, Y: [(Y, 0.2)])
    one_room = run_of(probe_cands, path=[[9, 1.5], [13, 3.5], [9, 3.5]])
    out = run_all([empty, low, one_room], params=DecisionParams(score_floor=0.5))
    st_ = out.state[:, :, OURS]
    assert (st_[:2] == 0).all()
    assert set(out.reason[0, :, OURS].tolist()) == {1}
    assert set(out.reason[1, :, OURS].tolist()) == {2}
    # One room of a row of congruent rooms: unsaturated (DEFER) until b_min = 3 disjoint
    # windows have champions, then saturated but never a commit (its copies stay feasible).
    assert st_[2, :2].tolist() == [0, 0] and set(out.reason[2, :2, OURS].tolist()) == {4}
    assert (st_[2, 2:] != 2).all()
    assert np.isfinite(out.anchor).all()


def test_nan_candidates_are_rejected_and_counted():
    base = run_of(probe_cands)
    bad = dict(base)
    bad["H"] = base["H"].copy()
    bad["score"] = base["score"].copy()
    bad["mask"] = base["mask"].copy()
    bad["H"][:, 5] = np.nan
    bad["score"][:, 5] = 5.0
    bad["mask"][:, 5] = True
    _, _, _, n_bad = sanitize(bad["H"], bad["score"], bad["mask"])
    assert np.asarray(n_bad).tolist() == [1] * K
    a, b = run_all([base]), run_all([bad])
    np.testing.assert_array_equal(a.state, b.state)
    assert np.isfinite(b.anchor).all() and np.isfinite(b.c_winner).all()
    assert b.n_rejected[0, :, OURS].tolist() == list(range(1, K + 1))  # counted, cumulative


FIELDS = ("state", "kind", "b1", "b2", "margin", "n_groups", "n_champions")


def assert_same(a, b, v=slice(0, 5)):
    for f in FIELDS:
        np.testing.assert_array_equal(getattr(a, f)[..., v], getattr(b, f)[..., v], err_msg=f)
    np.testing.assert_allclose(a.anchor[..., v, :], b.anchor[..., v, :], atol=1e-4)
    np.testing.assert_allclose(a.tau[..., v, :], b.tau[..., v, :], atol=1e-4)


@functools.cache
def base():
    """The reference run (built at first use, not at import: collection stays light)."""
    return run_of(probe_cands)


@functools.cache
def base_out():
    """``base()`` decided (at first use: collection stays free of compilation)."""
    return run_all([base()])


@settings(max_examples=6)
@given(st.integers(1, 12), st.integers(0, 2**31 - 1))
def test_c2_immunity_flooding_below_top1(n, seed):
    rng = np.random.default_rng(seed)
    run = {k: np.array(v, copy=True) for k, v in base().items()}
    j0 = int(run["mask"][0].sum())
    for k in range(K):
        top = run["score"][k][run["mask"][k]].max()
        m = min(n, J - j0)
        near_alias = run["H"][k, 1] + rng.normal(0, 0.3, (m, 3)) * [1, 1, 0.05]
        anywhere = np.concatenate([rng.uniform(-10, 30, (m, 2)), rng.uniform(-3, 3, (m, 1))], -1)
        pick = rng.random(m) < 0.5
        run["H"][k, j0 : j0 + m] = np.where(pick[:, None], near_alias, anywhere)
        run["score"][k, j0 : j0 + m] = top * rng.uniform(0.0, 0.999, m)
        run["mask"][k, j0 : j0 + m] = True
    out = run_all([run])
    assert_same(base_out(), out)


def test_support_flips_under_flooding_while_ours_does_not():
    run = {k: np.array(v, copy=True) for k, v in base().items()}
    for k in range(K):
        run["H"][k, 3:13] = run["H"][k, 1] + np.linspace(-0.2, 0.2, 10)[:, None] * [1, 1, 0]
        run["score"][k, 3:13] = 0.5
        run["mask"][k, 3:13] = True
    out = run_all([run])
    assert_same(base_out(), out)
    sup = NAMES.index("support")
    a0, a1 = base_out().anchor[0, -1, sup], out.anchor[0, -1, sup]
    assert float(se2.distance_pair(a0, A)[0]) < 0.5
    assert float(se2.distance_pair(a1, A)[0]) > 5.0


@settings(max_examples=4)
@given(st.integers(0, 2**31 - 1))
def test_permutation_invariance(seed):
    rng = np.random.default_rng(seed)
    run = run_of(lattice_cands)
    perm = rng.permutation(J)
    run2 = dict(run, H=run["H"][:, perm], score=run["score"][:, perm], mask=run["mask"][:, perm])
    assert_same(run_all([run]), run_all([run2]), v=slice(None))


def test_rigid_motion_equivariance():
    """Moving the plan and the anchors by ``g`` moves every decision by ``g``. Exactly for the
    variants that read the plan through the gate only; the certifying ones re-score the
    evidence on the moved plan's rasters, whose discretisation perturbs the scores by a few
    hundredths, so the first commit may move by a window or two where an advantage sits at
    the margin."""
    g = np.array([4.0, -6.0, 0.6])
    maps_g = maps_of(row_of_rooms().transformed(g))
    run = run_of(lattice_cands)
    run_g = dict(run, H=np.asarray(se2.compose(g, run["H"]), np.float32))
    a, b = run_all([run]), run_all([run_g], maps=maps_g)
    exact = [NAMES.index(n) for n in ("paper", "no_probe", "consensus_only")]
    for f in ("state", "kind", "b1", "b2"):
        np.testing.assert_array_equal(getattr(a, f)[..., exact], getattr(b, f)[..., exact], f)
    first = lambda s: int(np.argmax(np.append(np.asarray(s) == 2, True)))  # noqa: E731
    for n in ("ours", "ours_b2_d1", "ours_b4_d2"):
        i = NAMES.index(n)
        assert abs(first(a.state[0, :, i]) - first(b.state[0, :, i])) <= 2, n
    np.testing.assert_array_equal(a.b1, b.b1)
    moved = np.asarray(se2.compose(g, a.anchor[..., exact, :]))
    dxy, dth = se2.distance_pair(moved, b.anchor[..., exact, :])
    assert float(jnp.max(dxy)) < 1e-3 and float(jnp.max(dth)) < 1e-4
    tr = (a.kind[..., exact] == 1) & (b.kind[..., exact] == 1)
    rot = np.asarray(se2.rotate(g[2], a.tau[..., exact, :][tr]))
    np.testing.assert_allclose(rot, b.tau[..., exact, :][tr], atol=1e-3)


def test_multimodal_in_non_congruent_rooms():
    maps3 = maps_of(three_rooms())
    path = [[3, 3], [10, 3], [16, 3], [10, 3]]

    def cands(k, Y):  # champions split between two rooms, no congruent offset
        return [(Y, 1.0), (shift(Y, 7.0), 1.1 if k % 2 else 0.8)]

    out = run_all([make_run(walk(path), A, K, cands, J=J, fp=three_rooms())], maps=maps3)
    d = ours(out)
    assert (d.kind[d.state == 1] != 1).all()
    assert (d.kind == 2).any()


def test_a_runner_up_group_the_scans_rule_out_does_not_hold_the_margin():
    """Champions alternate between the truth and the same path 7 m along, in the smaller room
    (gate-feasible, non-congruent): the raw counts tie (B1 = B2), so the paper's layer stays
    AMBIGUOUS; the scans contradict the shifted placement, so under the certification that
    group no longer counts against the winner and ours commits, at the truth."""
    maps3 = maps_of(three_rooms())
    path = [[8, 1.5], [12.5, 1.5], [12.5, 4.5], [8, 4.5], [8, 1.5], [12.5, 1.5]]

    def cands(k, Y):
        return [(Y, 1.0), (shift(Y, -7.0), 1.1 if k % 2 else 0.8)]

    run = make_run(walk(path), A, K, cands, J=J, fp=three_rooms())
    out = run_all([run], maps=maps3)
    paper = jax.tree.map(lambda x: x[0, :, NAMES.index("paper")], out)
    d = ours(out)
    assert 2 not in paper.state.tolist()
    assert paper.b2[4] == 2 and paper.b1[4] == 3  # tied in the raw counts
    assert d.state[4] == 2 and d.b2[4] == 0 and d.margin[4] == 3
    com = d.state == 2
    assert com[4:].all()
    dxy, dth = se2.distance_pair(d.anchor[com], A[None])
    assert float(np.max(dxy)) < 0.05 and float(np.max(dth)) < 1e-3


def test_threshold_sweep_does_not_recompile():
    run = run_of(lattice_cands)
    run_all([run])
    before = TRACES["scan_runs"]
    for tau_c in (0.3, 0.6, 0.9):
        run_all([run], params=DecisionParams(tau_c=tau_c, delta_xy=1.0))
    assert TRACES["scan_runs"] == before


def test_frame_has_one_row_per_run_window_lane():
    spec = lanes_of()[2]
    df = to_frame(base_out(), spec)
    assert len(df) == K * len(NAMES)
    assert {"state", "kind", "x", "y", "yaw_deg", "tau_x", "B1", "B2", "margin"} <= set(df.columns)


def test_a_robot_calling_update_decides_as_the_batch():
    """The robot's path (one jitted ``update`` per window, unbatched) and the batch's (``vmap``
    over runs of ``lax.scan(update)``) are one function: the same decisions."""
    run = run_of(lattice_cands)
    out = ours(run_all([run]))
    p, lanes, spec = lanes_of(ours=("ours",), baselines=False)
    maps = jax.tree.map(lambda a: a[0], ROW)
    state = layer.init(maps, p.as_arrays(), CAPS, jax.tree.map(jnp.asarray, lanes), spec)
    ev = evidence_of(run)
    for k in range(K):
        state, d = step()(state, window(ev, k))
        d = jax.tree.map(lambda a: np.asarray(a[0]), d)
        assert int(d.state) == out.state[k] and int(d.kind) == out.kind[k], k
        assert int(d.b1) == out.b1[k] and int(d.b2) == out.b2[k]
        np.testing.assert_allclose(d.anchor, out.anchor[k], atol=1e-4)


def _brute_disjoint(members, start, end):
    """Largest set of member windows that pairwise share no sample (exhaustive)."""
    import itertools

    idx = [k for k in range(len(start)) if members[k]]
    best = 0
    for r in range(1, len(idx) + 1):
        for sub in itertools.combinations(idx, r):
            if all(start[b] > end[a] for a, b in zip(sub, sub[1:], strict=False)):
                best = max(best, r)
    return best


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.booleans(), min_size=1, max_size=9),
    st.integers(2, 12),
    st.integers(4, 40),
)
def test_independent_count_is_the_largest_scan_disjoint_set(members, step, length):
    """Proposition 1's independence by construction: B_m counts champions whose windows share
    no scan, and is the largest such set (windows = intervals, equally spaced like the
    sliding windows)."""
    from mfcl_jax.decision.consensus import disjoint_count

    k = len(members)
    start = np.arange(k) * step
    end = start + length - 1
    got = int(disjoint_count(jnp.asarray([members]), jnp.asarray(start), jnp.asarray(end))[0])
    assert got == _brute_disjoint(members, start, end)


def test_three_overlapping_windows_are_one_vote():
    """d_s = 6 m, step 2 m, 0.25 m keyframes: window k holds keyframes 8k .. 8k + 24, so
    windows k .. k + 3 share scans (k + 3 starts on k's last scan) and k + 4 does not."""
    from mfcl_jax.decision.consensus import disjoint_count

    start = np.arange(10) * 8
    end = start + 24
    one = np.zeros((1, 10), bool)
    one[0, [2, 3, 4]] = True
    assert int(disjoint_count(jnp.asarray(one), start, end)[0]) == 1
    assert int(disjoint_count(jnp.ones((1, 10), bool), start, end)[0]) == 3  # 0, 4, 8


def test_a_path_that_leaves_the_map_is_never_committed():
    """The front-end agrees on one anchor in every window, but under it the odometry walks
    out of the building through its end wall: a typed DEFER with its reason, never a commit."""
    out_path = [[3, 2.5], [26, 2.5], [40, 2.5]]  # the row ends at x = 4 pitches
    run = make_run(walk(out_path, step=40.0 / (T - 1)), A, K, probe_cands, J=J, fp=ROW_FP)
    d = ours(run_all([run]))
    names = ["DEFER", "AMBIGUOUS", "COMMIT"]
    states = [names[s] for s in d.state]
    assert "COMMIT" not in states[-3:], states  # once the path is outside, no commit stands
    assert states[-1] == "DEFER"
    why = REASONS[int(d.reason[-1])]
    assert why in ("winner infeasible", "no feasible champion", "commit infeasible"), why
    # the same candidates along a path that stays inside commit
    inside = make_run(walk([[3, 2.5], [26, 2.5]], step=23.0 / (T - 1)), A, K, probe_cands, J=J,
                      fp=ROW_FP)  # fmt: skip
    assert names[int(ours(run_all([inside])).state[-1])] == "COMMIT"


def test_a_restart_decides_the_new_segment_as_a_run_of_its_own():
    """An odometry jump: the layer starts over at the window flagged ``restart``; the
    windows after it are decided as the same windows would be in a run of their own."""
    run = run_of(probe_cands)
    one = evidence_of(run)
    two = jax.tree.map(lambda a: np.concatenate([a, a]), one)  # the walk again, after a jump
    assert two.restart.tolist() == [True] + [False] * (K - 1) + [True] + [False] * (K - 1)
    two = type(two)(**{**two.__dict__, "last": np.arange(2 * K) == 2 * K - 1})
    p, lanes, spec = lanes_of(ours=("ours",), baselines=False)
    state = layer.init(jax.tree.map(lambda a: a[0], ROW), p.as_arrays(),
                       CAPS, jax.tree.map(jnp.asarray, lanes), spec)  # fmt: skip
    _, d = stepwise(state, two)
    first, again = (jax.tree.map(lambda a, s=s: np.asarray(a)[s, 0], d)
                    for s in (slice(0, K), slice(K, 2 * K)))  # fmt: skip
    for f in ("state", "kind", "b1", "b2", "reason"):
        np.testing.assert_array_equal(getattr(first, f), getattr(again, f), err_msg=f)
    np.testing.assert_allclose(first.anchor, again.anchor, atol=1e-5)
    assert 2 in first.state.tolist()


def test_a_run_of_500_windows_outlives_the_capacities_and_says_so():
    """A long run: the history keeps the newest ``CAPS.windows`` windows and the newest
    ``CAPS.traj`` keyframes (fixed shapes, so every window costs the same); older windows leave
    the consensus and are counted (``Decision.dropped``), a commit keeps being tracked, the
    path keeps its distance, and no number turns non-finite."""
    run = run_of(probe_cands)
    one = evidence_of(run)
    n = 500
    reps = -(-n // K)
    # the same walk again and again, without a restart: the path goes on (a loop)
    many = jax.tree.map(lambda a: np.concatenate([a] * reps)[:n], one)
    ends = np.asarray(run["window_end"])
    starts = np.concatenate([np.asarray(run["window_start"]) + r * (ends[-1] + 1)
                             for r in range(reps)])[:n]  # fmt: skip
    many = type(many)(**{**many.__dict__, "restart": np.arange(n) == 0,
                         "start": starts.astype(np.int32),
                         "head": np.zeros_like(one.head[:1].repeat(n, 0)),
                         "head_mask": np.zeros_like(one.head_mask[:1].repeat(n, 0)),
                         "last": np.arange(n) == n - 1})  # fmt: skip
    first = jax.tree.map(lambda a: a[:1], one)  # window 1 brings its whole keyframe prefix
    p, lanes, spec = lanes_of(ours=("ours",), baselines=False)
    state = layer.init(jax.tree.map(lambda a: a[0], ROW), p.as_arrays(),
                       CAPS, jax.tree.map(jnp.asarray, lanes), spec)  # fmt: skip
    state, d0 = step()(state, window(first, 0))
    rest = jax.tree.map(lambda a: a[1:], many)
    rest = type(rest)(**{**rest.__dict__, "restart": np.zeros(n - 1, bool)})
    state, d = stepwise(state, rest)
    d = jax.tree.map(lambda a: np.asarray(a)[:, 0], d)
    assert d.dropped[-1] == n - K  # every window beyond the capacity is counted
    assert (np.diff(d.dropped) >= 0).all() and d.dropped[K - 2] == 0
    assert int(state.history.n) == K and int(state.path.n) == T
    assert int(state.path.total) > T  # keyframes kept counting past the buffer
    assert 2 in d.state.tolist() and d.state[-1] == 2  # the commit is held to the end
    assert np.isfinite(d.anchor).all() and np.isfinite(float(state.path.dist))
    dxy, _ = se2.distance_pair(d.anchor[-1], A)
    assert float(dxy) < 0.1
