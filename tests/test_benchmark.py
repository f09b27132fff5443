"""The generalisation benchmark: option checks, a small end-to-end run, and the multirun merge.

The reduced configuration (one procedural family, one building, one walk, one fault axis,
every kind of policy) exercises the whole path: recordings -> windows -> front-end -> labels ->
decisions -> particle filter -> scores -> tables and figures.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from mfcl_jax.bench.config import BenchmarkConfig, BenchmarkError, validate
from mfcl_jax.bench.main import merge, read_runs, run_benchmark
from mfcl_jax.sources.logs import DATA

needs_data = pytest.mark.skipif(
    not (DATA / "laser").is_dir(), reason=f"real data folder {DATA / 'laser'} is absent"
)


@pytest.mark.parametrize(
    "kw, needle",
    [
        (dict(families=["castle"]), "families='castle'"),
        (dict(policies=["ours", "oracle"]), "policies='oracle'"),
        (dict(seeds=0), "seeds=0"),
        (dict(seeds=-2), "seeds=-2"),
        (dict(log_length=5.0), "log_length=5.0"),
        (dict(faults=["earthquake"]), "faults='earthquake'"),
        (dict(families=[]), "families=[]"),
    ],
)
def test_bad_options_fail_before_any_work(kw, needle):
    with pytest.raises(BenchmarkError, match=needle.replace("[", r"\[").replace("]", r"\]")):
        validate(BenchmarkConfig(**kw))


@needs_data
def test_more_log_windows_than_a_log_holds_fail_before_any_work(tmp_path):
    cfg = BenchmarkConfig(families=["log:freiburg-101"], log_windows=9, out=str(tmp_path / "b"))
    with pytest.raises(BenchmarkError, match="log_windows=9 with log_length=45.*freiburg-101"):
        run_benchmark(cfg)
    assert not (tmp_path / "b").exists()


SMALL = dict(
    families=["bays"],
    seeds=1,
    walks=1,
    faults=["restart"],
    fault_seeds=1,
    policies=["ours", "paper", "single_shot", "gate_only", "mcl"],
    mcl_particles=512,
    figures=True,
    progress=False,
)


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """The small benchmark's output folder, its tables and what ``collect`` kept (the light
    recordings and the windows, for checks against the recordings' own odometry)."""
    import mfcl_jax.bench.main as bench_main

    root = tmp_path_factory.mktemp("bench")
    cfg = BenchmarkConfig(**SMALL, out=str(root / "one"), cache=str(root / "cache"))
    kept = []

    def spy(*a, **kw):
        kept.append(collect(*a, **kw))
        return kept[-1]

    collect = bench_main.collect
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bench_main, "collect", spy)
        tables = run_benchmark(cfg)
    return root, tables, kept[0]


def test_small_benchmark_writes_every_table(small):
    root, tables, _ = small
    out = root / "one"
    for name in ("runs.csv", "labels.csv", "families.md", "overall.md", "risk_coverage.csv",
                 "risk_coverage.png", "faults/restart.md", "faults/restart.png",
                 "windows.csv.gz", "timings.md", "families/bays.png", "margins.md",
                 "commit_distance.png"):  # fmt: skip
        assert (out / name).is_file(), name
    fam = tables["families"]
    assert set(fam["policy"]) == set(SMALL["policies"])
    ours = fam[(fam["family"] == "all") & (fam["policy"] == "ours")].iloc[0]
    assert ours["runs"] == 1 and 0 <= ours["identifiable"] <= 1
    runs = read_runs([out])
    # every policy is scored on the same runs, and the fault run restarts its odometry
    assert runs.groupby("policy")["name"].nunique().nunique() == 1
    assert set(runs["fault"]) == {"", "restart"}
    rc = tables["risk_coverage"]
    assert (rc.groupby("policy")["set"].nunique() > 1).all()  # a curve, not a point
    assert rc["false_rate"].between(0, 1).all() and rc["coverage"].between(0, 1).all()


def _metres_from_odometry(rec, w) -> np.ndarray:
    """Metres travelled by the end of each window, straight from the recording's odometry:
    the path over every scan up to the window's last one, an odometry jump counting nothing
    (a simulated walk keeps every scan as a keyframe)."""
    from mfcl_jax.windows import odometry_segments

    odo = np.asarray(rec.seq.odometry, np.float64)
    seg = odometry_segments(odo, rec.seq.times)
    step = np.linalg.norm(np.diff(odo[:, :2], axis=0), axis=1) * (np.diff(seg) == 0)
    path = np.concatenate([[0.0], np.cumsum(step)])
    return path[w.last_scan()]


def test_distance_to_commit_is_the_odometry_travelled(small):
    """``commit_m`` / ``oracle_m`` / ``false_m`` are the metres the run's own odometry
    travelled by the end of the first commit / oracle / first wrong COMMIT window, for every
    policy (the particle filter's rows included), from the run's start across a restart; the
    tables' medians are over the runs of ``median_delay``."""
    root, tables, col = small
    runs = read_runs([root / "one"])
    wins = [w for b in col.batches for w in b.windows]
    metres = [_metres_from_odometry(r, w) for r, w in zip(col.recordings, wins, strict=True)]
    restarted = [len(np.unique(w.segments)) > 1 for w in wins]
    assert any(restarted), "no restart run splits its odometry: the restart case is untested"
    for r, m in enumerate(metres):
        assert np.all(np.diff(m) > 0)  # each window ends further along
        if not restarted[r]:  # windows are cut every 2 m of travel, d_s = 6 m long
            assert np.all(m >= 6.0 + 2.0 * np.arange(len(m)) - 1e-6)
    # every window of every policy (the filter's too), a restart run's after its split included
    w = pd.read_csv(root / "one" / "windows.csv.gz")
    assert {"ours", "mcl"} <= set(w["policy"]) and w["metres"].notna().all()
    want = [metres[r][k - 1] for r, k in zip(w["run"], w["k"], strict=True)]
    np.testing.assert_allclose(w["metres"], want, rtol=1e-3)
    com = runs[runs["committed"]]
    assert set(com["policy"]) >= {"mcl"}
    for row in runs.itertuples():
        m = metres[row.run]
        for col_m, k in (("commit_m", row.k), ("oracle_m", row.oracle_k)):
            got = getattr(row, col_m)
            if np.isfinite(k):
                assert got == pytest.approx(m[int(k) - 1], rel=1e-5), (row.policy, col_m, k)
            else:
                assert np.isnan(got), (row.policy, col_m)
        assert np.isnan(row.commit_m) == (not row.committed)
        assert np.isnan(row.false_m) == (not row.any_false)
        if row.any_false:
            assert row.false_m >= row.commit_m - 1e-9
        if row.committed and np.isfinite(row.oracle_k) and row.k >= row.oracle_k:
            assert row.oracle_m <= row.commit_m + 1e-9
        if row.correct_run and row.identifiable:
            assert row.delay_m == pytest.approx(row.commit_m - row.oracle_m, abs=1e-4)
            assert np.sign(row.delay_m) == np.sign(row.delay)
        else:
            assert np.isnan(row.delay_m)
    fam = tables["families"].set_index(["family", "policy"])
    nom = runs[(runs["fault"] == "") & (runs["set"] == 1)]
    for pol, g in nom.groupby("policy"):
        ok = g[g["correct_run"] & g["identifiable"]]
        for c, src in (("median_commit_m", "commit_m"), ("median_delay_m", "delay_m")):
            want = ok[src].median() if len(ok) else np.nan
            assert fam.loc[("all", pol), c] == pytest.approx(want, nan_ok=True), (pol, c)
    assert {"median_commit_m", "median_delay_m"} <= set(tables["overall"].columns)
    assert {"median_commit_m", "median_delay_m"} <= set(tables["sources"].columns)


def test_run_table_gives_the_metres_of_the_first_commit_the_oracle_and_the_first_wrong_one():
    """A hand-made scored table: the metres come from the first COMMIT window, the oracle
    window and the first wrong COMMIT window; the delay in metres and the tables' medians are
    over the identifiable runs committed correctly, as ``median_delay``."""
    from mfcl_jax.bench.report import family_table, run_table
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
    lab = [RunLabel(True, o, np.ones(5, bool), 0, None) for o in (2, 2, 1, 3)]
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


def test_ratio_calibration_bins_the_tested_windows_and_counts_the_wrong_anchors():
    """Windows where the uniqueness test ran unvetoed, binned by ratio (edges at the lanes'
    thresholds, +inf in the last bin); vetoed (-inf), untested (NaN) and unjudged windows and
    other policies are left out; fault rows are counted apart."""
    from mfcl_jax.bench.calibration import EDGES, ratio_calibration

    lane = "ours_unique_a6"
    rows = [  # policy, fault, llr, correct
        (lane, None, 0.5, True), (lane, None, 0.5, False), (lane, None, 3.5, False),
        (lane, None, 5.0, True), (lane, None, np.inf, True), (lane, None, -np.inf, False),
        (lane, None, np.nan, False), (lane, None, 2.5, None), ("ours", None, 5.0, False),
        (lane, "drift", 5.0, False),
    ]  # fmt: skip
    w = pd.DataFrame(rows, columns=["policy", "fault", "llr", "correct"])
    t = ratio_calibration(w)
    assert len(t) == len(EDGES) - 1 and t["bound"].iloc[0] == 1.0
    assert t["windows"].tolist() == [2, 0, 0, 1, 1, 0, 0, 1]
    assert t["wrong"].tolist() == [1, 0, 0, 1, 0, 0, 0, 0]
    assert t["fault_windows"].sum() == 1 and t["fault_wrong"].tolist()[4] == 1
    assert t["bound"].iloc[4] == pytest.approx(1e-2)


def test_commit_margins_say_how_close_the_right_commits_came_to_the_line():
    """Right COMMIT windows give the largest errors and share of the 1 m / 5 deg line; a window
    past the line counts as wrong and is left out of the maxima; non-COMMIT windows and other
    policies are ignored; fault rows are counted per (run, fault, level)."""
    from mfcl_jax.bench.report import commit_margins

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


def test_merge_of_jobs_gives_the_same_tables(small, tmp_path):
    """A multirun split (here: the nominal runs and the fault axis as two jobs' outputs)
    merged by ``merge`` gives the single run's tables: one code path from ``runs.csv``."""
    root, tables, _ = small
    runs = read_runs([root / "one"])
    jobs = []
    for name, part in (("a", runs[runs["fault"] == ""]), ("b", runs[runs["fault"] != ""])):
        (tmp_path / name).mkdir()
        part.to_csv(tmp_path / name / "runs.csv", index=False)
        jobs.append(tmp_path / name)
    merged = merge(jobs, tmp_path / "merged", SMALL["policies"])
    for name in ("families", "sources", "risk_coverage", "faults/restart"):
        a = tables[name].reset_index(drop=True)
        b = merged[name].reset_index(drop=True)
        pd.testing.assert_frame_equal(a, b, check_dtype=False, check_exact=False, rtol=1e-6)


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
