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


def test_merge_refuses_jobs_that_overlap_or_ran_at_different_window_lengths(small, tmp_path):
    """Two jobs holding the same run (as jobs split by fault axis would: each repeats the
    nominal runs) or runs of different ``d_s`` are not one benchmark: ``merge`` names the run
    or the jobs and writes nothing; ``runs.csv`` from before the ``d_s`` column merges."""
    root, _, _ = small
    runs = read_runs([root / "one"])
    assert set(runs["d_s"]) == {6.0}
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        runs.to_csv(tmp_path / name / "runs.csv", index=False)
    with pytest.raises(
        BenchmarkError, match=r"run 'bays-0/A/s0' \(nominal, policy .*more than one job"
    ):
        merge([tmp_path / "a", tmp_path / "b"], tmp_path / "out", SMALL["policies"])
    nominal, faulty = runs[runs["fault"] == ""], runs[runs["fault"] != ""]
    nominal.to_csv(tmp_path / "a" / "runs.csv", index=False)
    faulty.assign(d_s=7.0).to_csv(tmp_path / "b" / "runs.csv", index=False)
    with pytest.raises(BenchmarkError, match="different window lengths.*d_s=6.*d_s=7"):
        merge([tmp_path / "a", tmp_path / "b"], tmp_path / "out", SMALL["policies"])
    assert not (tmp_path / "out").exists()
    faulty.drop(columns="d_s").to_csv(tmp_path / "b" / "runs.csv", index=False)
    merged = merge([tmp_path / "a", tmp_path / "b"], tmp_path / "out", SMALL["policies"])
    assert len(merged["families"])
