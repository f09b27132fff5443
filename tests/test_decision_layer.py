"""Decision layer end to end: the states on a row of congruent rooms (lattice, probe, DEFER,
rejected candidates, a path out of the map), non-congruent rooms, the frame of a batch and a
threshold sweep that does not recompile.

All evaluations share one padded shape bucket so the jitted layer compiles once per lane set.
"""

import jax
import numpy as np

from mfcl_jax import se2
from mfcl_jax.decision import REASONS, DecisionParams, sanitize, to_frame
from mfcl_jax.decision.runs import TRACES
from mfcl_jax.sim.synthetic import PITCH, make_run, shift, three_rooms, walk
from tests._decision_row import (
    NAMES,
    OURS,
    ROW_FP,
    A,
    base_out,
    lattice_cands,
    ours,
    probe_cands,
    run_all,
    run_of,
)
from tests._layer import J, K, T, lanes_of, maps_of


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
    # the uniqueness test's placement only where a lane runs it (the study's raw table keeps
    # its columns)
    assert not spec.unique and "test_x" not in df


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
