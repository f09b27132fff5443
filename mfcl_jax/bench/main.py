"""``python -m experiments.benchmark``: the whole benchmark, and the merge of multirun jobs.

``run_benchmark`` writes ``runs.csv`` (one row per run x policy x threshold set: the raw
result every table is rebuilt from), ``labels.csv`` and the tables and figures. A multirun job
writes the same files into its own folder; ``merge`` joins the jobs' ``runs.csv`` and rebuilds
identical tables (``write_tables`` is the one code path from ``runs.csv`` to every table).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pandas as pd

from mfcl_jax.bench import suite
from mfcl_jax.bench.config import FAULTS, PROCEDURAL, BenchmarkConfig, BenchmarkError, validate
from mfcl_jax.bench.run import collect, decide_and_score
from mfcl_jax.io.atomic import atomic_write
from mfcl_jax.report import benchmark as report
from mfcl_jax.report import jobs
from mfcl_jax.report.calibration import (
    commit_margins,
    fault_level_calibration,
    grid_calibration,
    ratio_calibration,
)
from mfcl_jax.report.tables import write_table

__all__ = ["run_benchmark", "write_tables", "write_margins", "read_runs", "merge"]


def _groups(cfg: BenchmarkConfig):
    for fam in cfg.families:
        sub = BenchmarkConfig(**{**cfg.__dict__, "families": [fam], "faults": []})
        yield fam, (lambda s=sub: suite.nominal_recordings(s))
    procedural = [f for f in cfg.families if f in PROCEDURAL]
    for axis in cfg.faults if procedural else []:
        sub = BenchmarkConfig(**{**cfg.__dict__, "faults": [axis]})
        yield f"fault {axis}", (lambda s=sub: suite.fault_recordings(s))


def run_benchmark(cfg: BenchmarkConfig) -> dict:
    """Runs the configured benchmark and writes every output under ``cfg.out``."""
    t_start = time.perf_counter()
    cfg = validate(cfg)
    suite.check_logs(cfg)  # reads the logs' travel: before any work starts
    ours = [p for p in cfg.policies if p not in ("single_shot", "support", "confidence",
                                                 "gate_only", "mcl")]  # fmt: skip
    mcl_runner = None
    if "mcl" in cfg.policies:
        from mfcl_jax.bench.peer import make_mcl_runner

        mcl_runner = make_mcl_runner(cfg)
    col = collect(cfg, _groups(cfg), mcl_runner)
    scored = decide_and_score(col, cfg, ours or ["ours"])
    runs = report.run_table(scored, col.labels)
    runs = pd.concat([runs, nominal_level_rows(runs, cfg)], ignore_index=True)
    _write_windows(scored, col.labels, Path(cfg.out))
    keep = set(cfg.policies)
    runs = runs[runs["policy"].isin(keep)].assign(d_s=float(cfg.d_s))
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "runs.csv", runs.to_csv(index=False, float_format="%.6g"))
    runs = read_runs([out])  # tables come from the file, as in ``merge``: identical tables
    labels = runs.drop_duplicates("name")[
        ["name", "family", "fault", "level", "identifiable", "oracle_k", "n_alternatives",
         "label_strength", "oracle_m"]
    ]  # fmt: skip
    atomic_write(out / "labels.csv", labels.to_csv(index=False))
    col.tick("total", time.perf_counter() - t_start)
    tm = pd.DataFrame([dict(stage=k, seconds=round(v, 2)) for k, v in col.timings.items()])
    write_table(tm, out, "timings")
    tables = write_tables(runs, out, cfg.policies, cfg.figures)
    tables["margins"] = write_margins(out)
    if cfg.figures:
        _pictures(cfg, out)
    return tables


def nominal_level_rows(runs: pd.DataFrame, cfg: BenchmarkConfig) -> pd.DataFrame:
    """Rows of the fault axes' nominal levels: the nominal runs of the base set (first walk of
    each procedural family, seeds below ``fault_seeds``), tagged with the axis and level."""
    nom = runs[(runs["fault"].fillna("") == "") & (runs["source"] == "procedural")]
    nom = nom.sort_values("run", kind="stable")
    first = nom.drop_duplicates(["family", "seed"])[["family", "seed", "walk"]]
    base = nom.merge(first, on=["family", "seed", "walk"])
    parts = []
    for axis in cfg.faults:
        for fam, seed in first[["family", "seed"]].itertuples(index=False):
            if suite.reuses_nominal(cfg, axis, suite.NOMINAL_LEVEL.get(axis), fam, int(seed)) \
                    and int(seed) < cfg.fault_seeds:  # fmt: skip
                rows = base[(base["family"] == fam) & (base["seed"] == seed)]
                parts.append(rows.assign(fault=axis, level=str(suite.NOMINAL_LEVEL[axis])))
    return pd.concat(parts, ignore_index=True) if parts else runs.iloc[:0]


WINDOW_COLS = ["run", "name", "family", "fault", "level", "policy", "k", "state", "kind",
               "reason", "B1", "B2", "margin", "n_groups", "x", "y", "yaw_deg", "err_xy",
               "err_yaw_deg", "correct", "ident_k", "metres", "llr", "test_correct"]  # fmt: skip


def _write_windows(scored: pd.DataFrame, labels, out: Path) -> None:
    """Every window of every run at the default thresholds (``windows.csv.gz``), with the
    geometric label of the window: the raw material for reading a run's decision log."""
    from mfcl_jax.bench.run import DEFAULT_SET

    w = scored[scored["set"] == DEFAULT_SET].copy()
    ik = [lb.identifiable_k for lb in labels]
    w["ident_k"] = [
        bool(ik[r][k - 1]) if k - 1 < len(ik[r]) else False
        for r, k in zip(w["run"], w["k"], strict=True)
    ]
    out.mkdir(parents=True, exist_ok=True)
    w[[c for c in WINDOW_COLS if c in w]].to_csv(
        out / "windows.csv.gz", index=False, float_format="%.4g",
        compression={"method": "gzip", "mtime": 0},
    )  # fmt: skip


def _read_table(f: Path) -> pd.DataFrame:
    """A benchmark CSV as written: fault and level stay strings ("0.01", never 0.01), and only
    an empty cell is missing (a level named "none" stays a level)."""
    return pd.read_csv(f, dtype={"fault": str, "level": str}, keep_default_na=False,
                       na_values=[""])  # fmt: skip


def write_margins(out) -> pd.DataFrame:
    """``margins.csv/.md`` (``calibration.commit_margins``) and, where the uniqueness lanes ran,
    ``ratio_calibration.csv/.md`` and ``ratio_calibration_faults.csv/.md``
    (``calibration.ratio_calibration``, ``calibration.fault_level_calibration``) from the folder's
    ``windows.csv.gz``; returns the margins."""
    out = Path(out)
    f = out / "windows.csv.gz"
    if not f.is_file():
        raise FileNotFoundError(f"margins: {f} not found (run the benchmark first)")
    windows = _read_table(f)
    tab = commit_margins(windows)
    write_table(tab, out, "margins")
    if "llr" in windows and (windows["policy"] == "ours_unique_a6").any():
        write_table(ratio_calibration(windows), out, "ratio_calibration")
        write_table(fault_level_calibration(windows), out, "ratio_calibration_faults")
    if "llr" in windows and (windows["policy"] == "ours_grid_off").any():
        cal = grid_calibration(windows)
        write_table(cal, out, "grid_calibration")
        both = cal["group"].isin(["nominal", "all fault rows"])
        write_table(cal[both].reset_index(drop=True), out, "grid_calibration_summary")
    return tab


def write_tables(runs: pd.DataFrame, out, policies, draw: bool = True) -> dict:
    """Every table (and figure) from the run table."""
    out = Path(out)
    pols = [p for p in policies if p in set(runs["policy"])]
    tabs = {"families": report.family_table(runs, pols)}
    tabs["overall"] = tabs["families"][tabs["families"]["family"] == "all"].drop(columns="family")
    tabs["matrix"] = report.family_matrix(tabs["families"])
    tabs["sources"] = report.family_table(runs, pols, by="source")
    tabs["risk_coverage"] = report.risk_coverage(runs, pols)
    strength = report.label_strength(runs, pols)
    if not strength.empty:
        tabs["label_strength"] = strength
    for axis in FAULTS:
        t = report.fault_table(runs, axis, pols)
        if not t.empty:
            tabs[f"faults/{axis}"] = t
    ffl = report.first_false_level(runs, pols)
    if not ffl.empty:
        tabs["faults/first_false_level"] = ffl
    for name, df in tabs.items():
        write_table(df, out / Path(name).parent, Path(name).name)
    if draw:
        from mfcl_jax.report import plots_benchmark as figures

        figures.save(figures.risk_coverage_figure(tabs["risk_coverage"]), out / "risk_coverage.png")
        if "commit_m" in runs:
            fig = figures.commit_distance_figure(runs, pols)
            figures.save(fig, out / "commit_distance.png")
            fig = figures.risk_distance_figure(tabs["overall"])
            figures.save(fig, out / "risk_distance.png")
        for axis in FAULTS:
            if f"faults/{axis}" in tabs:
                fig = figures.fault_figure(tabs[f"faults/{axis}"], axis, FAULTS[axis])
                figures.save(fig, out / "faults" / f"{axis}.png")
    return tabs


def _pictures(cfg: BenchmarkConfig, out: Path) -> None:
    """One picture per family (seed 0) with its walks drawn."""
    from mfcl_jax.report.plots_scene import plot_family
    from mfcl_jax.sim import families

    for fam in cfg.families:
        if fam in PROCEDURAL:
            plot_family(families.make_scene(fam, 0), out / "families" / f"{fam}.png")


def read_runs(job_dirs) -> pd.DataFrame:
    """The ``runs.csv`` of one or more output folders, joined."""
    parts = []
    for d in job_dirs:
        f = Path(d) / "runs.csv"
        if not f.is_file():
            raise FileNotFoundError(f"merge: {f} not found (did the job finish?)")
        try:
            parts.append(_read_table(f).assign(_job=str(d)))
        except (ValueError, OSError) as e:  # a damaged job file
            raise BenchmarkError(f"merge: {f}: not a readable table ({e})") from e
    _check_one_benchmark(parts)
    runs = pd.concat(parts, ignore_index=True).drop(columns="_job")
    runs["fault"] = runs["fault"].fillna("")
    runs["level"] = runs["level"].fillna("")
    for c in ("committed", "any_false", "correct_run", "identifiable"):
        runs[c] = runs[c].astype(bool)
    return runs


def _check_one_benchmark(parts) -> None:
    """Jobs merge into one table only if they are parts of one benchmark: one window length
    ``d_s`` (``runs.csv`` written before the column existed is not checked) and no run (name,
    fault, level, policy, threshold set) in two jobs (jobs split by fault axis all repeat the
    nominal runs); otherwise a ``BenchmarkError`` naming the jobs."""
    d_s = {}
    for p in parts:
        for v in p["d_s"].dropna().unique() if "d_s" in p else ():
            d_s.setdefault(float(v), p["_job"].iat[0])
    if len(d_s) > 1:
        said = "; ".join(f"{job}: d_s={v:g}" for v, job in sorted(d_s.items()))
        raise BenchmarkError(
            f"merge: the jobs ran at different window lengths ({said}); a table over runs of "
            "different d_s mixes two benchmarks: merge the jobs of one d_s at a time"
        )
    key = ["name", "fault", "level", "policy", "set"]
    rows = pd.concat([p[[*key, "_job"]] for p in parts], ignore_index=True)
    rows = rows.fillna({"fault": "", "level": ""})
    found = jobs.repeated(rows, key)
    if found is not None:
        first, holders = found
        fault = f"fault {first['fault']} {first['level']}" if first["fault"] else "nominal"
        raise BenchmarkError(
            f"merge: run {first['name']!r} ({fault}, policy {first['policy']}, set "
            f"{first['set']}) is in {jobs.where(holders)}: the jobs overlap (split a multirun "
            "by families, not by fault axes: every axis repeats the nominal runs)"
        )


def merge(job_dirs, out, policies=None) -> dict:
    """Joins multirun jobs' ``runs.csv`` and rebuilds every table."""
    runs = read_runs(job_dirs)
    policies = policies or list(dict.fromkeys(runs["policy"]))
    print(f"merge: {len(job_dirs)} jobs, {runs['name'].nunique()} runs", file=sys.stderr)
    return write_tables(runs, out, policies)
