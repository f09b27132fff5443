"""The benchmark's tables on hand-made rows: metres to commit, ratio calibration, commit
margins, nominal fault levels, the front-end's recall; and its comma lists per multirun job."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from mfcl_jax.bench.config import BenchmarkConfig


def test_run_table_gives_the_metres_of_the_first_commit_the_oracle_and_the_first_wrong_one():
    """A hand-made scored table: the metres come from the first COMMIT window, the oracle
    window and the first wrong COMMIT window; the delay in metres and the tables' medians are
    over the identifiable runs committed correctly, as ``median_delay``."""
    from mfcl_jax.report.benchmark import family_table, label_strength, run_table
    from mfcl_jax.score.identifiability import RunLabel

    metres = [6.0, 8.0, 10.5, 12.0, 14.2]
    states = {  # run: states of windows 1..5 and whether each is right
        0: ("DEFER DEFER COMMIT COMMIT COMMIT", [1, 1, 1, 1, 1]),  # right at k=3, oracle 2
        1: ("DEFER COMMIT COMMIT DEFER COMMIT", [1, 1, 1, 1, 0]),  # wrong again at k=5
        2: ("DEFER DEFER DEFER COMMIT COMMIT", [1, 1, 1, 1, 1]),  # right at k=4, oracle 1
        3: ("DEFER DEFER DEFER DEFER DEFER", [0, 0, 0, 0, 0]),  # abstains
    }
    rows = []
    for run, (st, ok) in states.items():
        for k, (s, c) in enumerate(zip(st.split(), ok, strict=True), start=1):
            rows.append(dict(run=run, policy="ours", set=1, k=k, state=s, correct=bool(c),
                             err_xy=0.1, err_yaw_deg=1.0, metres=metres[k - 1], family="f",
                             fault="", source="procedural"))  # fmt: skip
    lab = [RunLabel(True, o, np.ones(5, bool), 0, None, st)
           for o, st in zip((2, 2, 1, 3), (np.inf, 1.5, 1.04, 7.0), strict=True)]  # fmt: skip
    t = run_table(pd.DataFrame(rows), lab).set_index("run")
    assert t["commit_m"].tolist()[:3] == [10.5, 8.0, 12.0] and np.isnan(t.loc[3, "commit_m"])
    assert t["oracle_m"].tolist() == [8.0, 8.0, 6.0, 10.5]
    assert np.isnan(t.loc[0, "false_m"]) and t.loc[1, "false_m"] == 14.2
    assert t.loc[0, "delay_m"] == 2.5 and t.loc[2, "delay_m"] == 6.0
    assert np.isnan(t.loc[1, "delay_m"]) and np.isnan(t.loc[3, "delay_m"])  # false; abstains
    fam = family_table(t.reset_index(), ["ours"]).set_index("family")
    assert fam.loc["all", "median_delay"] == 2.0  # windows 1 and 3
    assert fam.loc["all", "median_commit_m"] == pytest.approx((10.5 + 12.0) / 2)
    assert fam.loc["all", "median_delay_m"] == pytest.approx((2.5 + 6.0) / 2)
    # coverage by how clearly each run was identified: runs 1 and 2 are marginal (1.5, 1.04;
    # run 1 committed falsely, run 2 right), runs 0 and 3 clear (0 right, 3 abstains)
    ls = label_strength(t.reset_index(), ["ours"]).iloc[0]
    counts = ls[["marginal", "marginal_covered", "clear", "clear_covered"]].tolist()
    assert counts == [2, 1, 2, 1]
    assert ls["coverage"].startswith("2/4") and ls["coverage_clear"].startswith("1/2")
    # a run without a strength (an older runs.csv merged in): no split at all
    older = t.reset_index().assign(label_strength=[np.inf, 1.5, np.nan, 7.0])
    assert label_strength(older, ["ours"]).empty


def test_ratio_calibration_bins_the_tested_windows_and_counts_the_wrong_anchors():
    """Windows where the uniqueness test ran unvetoed, binned by ratio (edges at the lanes'
    thresholds, +inf in the last bin); vetoed (-inf), untested (NaN) and unjudged windows and
    other policies are left out; fault rows are counted apart."""
    from mfcl_jax.report.calibration import EDGES, ratio_calibration

    lane = "ours_unique_a6"
    rows = [  # policy, fault, llr, correct
        (lane, None, 0.5, True), (lane, None, 0.5, False), (lane, None, 3.5, False),
        (lane, None, 5.0, True), (lane, None, np.inf, True), (lane, None, -np.inf, False),
        (lane, None, np.nan, False), (lane, None, 2.5, None), ("ours", None, 5.0, False),
        (lane, "drift", 5.0, False),
    ]  # fmt: skip
    w = pd.DataFrame(rows, columns=["policy", "fault", "llr", "correct"])
    t = ratio_calibration(w)
    # bins [0, 1), [1, 2), [2, 2.30), [2.30, 3), [3, 4.61), [4.61, 6.91), ..., [13.8, inf)
    assert len(t) == len(EDGES) - 1 == 9 and t["bound"].iloc[0] == 1.0
    assert t["windows"].tolist() == [2, 0, 0, 0, 1, 1, 0, 0, 1]
    assert t["wrong"].tolist() == [1, 0, 0, 0, 1, 0, 0, 0, 0]
    assert t["fault_windows"].sum() == 1 and t["fault_wrong"].tolist()[5] == 1
    assert t["bound"].iloc[3] == pytest.approx(1e-1) and t["bound"].iloc[5] == pytest.approx(1e-2)
    # judged by the test's own placement where the table records it (test_correct), not by
    # the reported anchor: a champion a few degrees off under a right A* is not a wrong A*
    w["test_correct"] = [True, False, True, True, True, None, None, None, None, False]
    t = ratio_calibration(w)
    assert t["windows"].tolist() == [2, 0, 0, 0, 1, 1, 0, 0, 1]
    assert t["wrong"].tolist() == [1, 0, 0, 0, 0, 0, 0, 0, 0]


def test_fault_level_calibration_counts_each_level_past_each_lanes_threshold():
    """Per (axis, level), nominal first and every fault row last: the judged windows and, per
    lane threshold log(1/alpha), those at or above it and the wrong ones among them."""
    from mfcl_jax.report.calibration import fault_level_calibration

    lane = "ours_unique_a6"
    rows = [  # policy, fault, level, llr, test_correct
        (lane, None, None, 5.0, True), (lane, None, None, 10.0, False),
        (lane, "drift", "0.01", 4.0, False), (lane, "drift", "0.01", 7.0, True),
        (lane, "drift", "0.02", 14.0, False), (lane, "drift", "0.02", -np.inf, False),
        (lane, "clutter", "0.3", np.nan, False), ("ours", "drift", "0.02", 20.0, False),
        (lane, "drift", "0.02", 3.0, None),
    ]  # fmt: skip
    w = pd.DataFrame(rows, columns=["policy", "fault", "level", "llr", "test_correct"])
    t = fault_level_calibration(w).set_index(["fault", "level"])
    assert list(t.index) == [("nominal", ""), ("drift", "0.01"), ("drift", "0.02"),
                             ("all fault rows", "")]  # fmt: skip
    assert t.loc[("nominal", ""), ["windows", "wrong"]].tolist() == [2, 1]
    assert t.loc[
        ("nominal", ""), ["windows_a2", "wrong_a2", "windows_a6", "wrong_a6"]
    ].tolist() == [2, 1, 0, 0]  # 10 nats: past 1e-4 (9.21), short of 1e-6 (13.8)
    assert t.loc[("nominal", ""), ["windows_a4", "wrong_a4"]].tolist() == [1, 1]
    # 1e-1 (2.30 nats): the 4-nat wrong window of drift 0.01 is past it, short of 1e-2 (4.61)
    assert t.loc[("drift", "0.01"), ["windows_a1", "wrong_a1"]].tolist() == [2, 1]
    assert t.loc[("all fault rows", ""), ["windows_a1", "wrong_a1"]].tolist() == [3, 2]
    assert t.loc[("drift", "0.01"), ["windows", "wrong", "windows_a2", "wrong_a2"]].tolist() == [
        2,
        1,
        1,
        0,
    ]
    assert t.loc[("drift", "0.02"), ["windows", "windows_a6", "wrong_a6"]].tolist() == [1, 1, 1]
    assert t.loc[("all fault rows", ""), ["windows", "wrong", "wrong_a2"]].tolist() == [3, 2, 1]


def test_score_rows_judge_the_uniqueness_tests_placement_by_the_same_line():
    """``test_correct``: the uniqueness test's placement (``test_x, test_y, test_yaw_deg``)
    against the truth by the 1 m / 5 deg line of ``correct``; missing where it did not run."""
    from mfcl_jax.score.decisions import score_rows

    t = np.array([0.0, 1.0, 2.0])
    odom = np.zeros((3, 3))
    gt = np.array([[1.0, 2.0, 0.1]] * 3)
    yaw = np.rad2deg(0.1)
    df = pd.DataFrame({"k": [1, 2, 3], "t": t, "x": [1.0] * 3, "y": [2.0] * 3,
                       "yaw_deg": [yaw + 6.0] * 3, "test_x": [1.0, 2.5, np.nan],
                       "test_y": [2.0, 2.0, np.nan], "test_yaw_deg": [yaw] * 3})  # fmt: skip
    s = score_rows(df, t, odom, t, gt)
    assert not s["correct"].any()  # the reported anchor is 6 deg off
    assert s["test_correct"].tolist()[:2] == [True, False] and pd.isna(s["test_correct"].iloc[2])


def test_commit_margins_say_how_close_the_right_commits_came_to_the_line():
    """Right COMMIT windows give the largest errors and share of the 1 m / 5 deg line; a window
    past the line counts as wrong and is left out of the maxima; non-COMMIT windows and other
    policies are ignored; fault rows are counted per (run, fault, level)."""
    from mfcl_jax.report.calibration import commit_margins

    rows = [  # name, family, fault, level, policy, state, err_xy, err_yaw_deg
        ("a/s0", "plain", None, None, "ours", "COMMIT", 0.10, 1.0),
        ("a/s0", "plain", None, None, "ours", "COMMIT", 0.30, 4.0),  # 0.8 of the line
        ("a/s0", "plain", None, None, "ours", "COMMIT", 1.50, 0.1),  # wrong
        ("a/s0", "plain", None, None, "ours", "DEFER", 9.00, 90.0),  # not a commit
        ("b/s0", "hall", None, None, "ours", "COMMIT", 0.60, 0.5),
        ("b/s0", "hall", None, None, "paper", "COMMIT", 0.99, 0.5),  # another policy
        ("a/s0", "plain", "drift", "0.01", "ours", "COMMIT", 0.20, 0.2),
        ("a/s0", "plain", "drift", "0.02", "ours", "COMMIT", 0.20, 0.2),
    ]
    w = pd.DataFrame(rows, columns=["name", "family", "fault", "level", "policy", "state",
                                    "err_xy", "err_yaw_deg"])  # fmt: skip
    t = commit_margins(w).set_index("group")
    assert list(t.index) == ["plain", "hall", "all nominal", "all fault rows"]
    assert t.loc["plain", "commit_windows"] == 3 and t.loc["plain", "wrong"] == 1
    assert t.loc["plain", "max_xy_m"] == pytest.approx(0.30)
    assert t.loc["plain", "use"] == pytest.approx(0.8) and t.loc["plain", "over_half"] == 1
    assert t.loc["hall", "use"] == pytest.approx(0.6)
    assert t.loc["all nominal", "commit_windows"] == 4 and t.loc["all nominal", "runs"] == 2
    assert t.loc["all fault rows", "runs"] == 2 and t.loc["all fault rows", "wrong"] == 0


def test_nominal_fault_levels_reuse_the_first_walk_of_the_base_set():
    from mfcl_jax.bench.main import nominal_level_rows

    rows = []
    for run, (fam, seed, walk, fault) in enumerate(
        [("bays", 0, "A", ""), ("bays", 0, "B", ""), ("bays", 1, "A", ""), ("hall", 0, "A", ""),
         ("bays", 0, "A", "drift")]
    ):  # fmt: skip
        for pol in ("ours", "mcl"):
            lvl = "0.02" if fault else ""
            rows.append(dict(run=run, policy=pol, set=1, family=fam, seed=seed, walk=walk,
                             fault=fault, level=lvl, source="procedural"))  # fmt: skip
    runs = pd.DataFrame(rows)
    cfg = BenchmarkConfig(families=["bays", "hall"], seeds=2, fault_seeds=1,
                          faults=["drift", "restart"])  # fmt: skip
    out = nominal_level_rows(runs, cfg)
    # drift has a nominal level (0.005); restart has none. Seed 1 is outside fault_seeds.
    assert set(out["fault"]) == {"drift"} and set(out["level"]) == {"0.005"}
    got = set(zip(out["family"], out["walk"], out["run"], strict=True))
    assert sorted(got) == [("bays", "A", 0), ("hall", "A", 3)]
    assert len(out) == 4  # two runs x two policies


def test_comma_lists_batch_in_one_run_and_split_per_job_in_a_multirun():
    from experiments.benchmark import batch_comma_lists

    assert batch_comma_lists(["x", "families=plain,bays"]) == ["x", "families=[plain,bays]"]
    # the schema takes lists only: one list per multirun job
    assert batch_comma_lists(["-m", "families=plain,bays", "seeds=2"]) == [
        "-m", "families=[plain],[bays]", "seeds=2"
    ]  # fmt: skip
    assert batch_comma_lists(["-m", "faults=[]"]) == ["-m", "faults=[]"]


def test_frontend_recall_scores_the_best_candidate_and_any():
    from mfcl_jax.bench.recall import recall_table, window_hits
    from mfcl_jax.frontend.candidates import Candidates

    pose = np.array([[[5.0, 0.0, 0.0], [0.2, 0.1, 0.02], [0.0, 0.0, 0.0]]] * 2, np.float32)
    score = np.array([[0.9, 0.5, 0.0], [0.4, 0.8, 0.0]], np.float32)
    mask = np.array([[True, True, False], [True, True, False]])
    c = Candidates(pose, score, mask, np.zeros(2, np.int32))
    Y = np.zeros(3)
    assert window_hits(c, 0, Y) == (2, False, True)  # best is 5 m off; the runner-up is right
    assert window_hits(c, 1, Y) == (2, True, True)
    c0 = Candidates(pose, score, np.zeros_like(mask), np.full(2, 3, np.int32))
    assert window_hits(c0, 0, Y) == (0, False, False)
    assert window_hits(c, 0, np.array([0.0, 0.0, np.radians(7.0)])) == (2, False, False)
    rows = pd.DataFrame(
        dict(
            family=["a", "a", "b"],
            variant="v",
            k=[1, 2, 1],
            n=[0, 3, 3],
            top1=[False, True, True],
            any=[False, True, True],
        )  # fmt: skip
    )
    t = recall_table(rows).set_index("family")
    assert t.loc["a", "windows"] == 2 and t.loc["a", "none"] == 0.5 and t.loc["a", "top1"] == 0.5
    assert t.loc["all", "windows"] == 3 and abs(t.loc["all", "top1"] - 2 / 3) < 1e-12
