"""``run_study``: the whole sweep in one process, and the merge of multirun job outputs."""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from mfcl_jax.config import StudyConfig
from mfcl_jax.decision.inputs import run_inputs
from mfcl_jax.decision.lanes import STRICT_IOU
from mfcl_jax.frontend.candidates import no_candidates
from mfcl_jax.report import jobs, tables
from mfcl_jax.report import study as report
from mfcl_jax.sim.scenes import get_scene
from mfcl_jax.study import density, pipeline

__all__ = ["run_study", "merge", "MergeError"]

RAW = "windows.csv.gz"


def _density_run(data, cfg: StudyConfig) -> int | None:
    """The run of ``cfg.density_run`` (``traj@d_s``) at the main seed (None: not simulated)."""
    traj, ds = cfg.density_run.split("@")
    sel = data.runs[
        (data.runs["scene"] == "three_rooms")
        & (data.runs["trajectory"] == traj)
        & (data.runs["d_s"] == float(ds))
        & (data.runs["seed"] == cfg.main_seed)
    ]
    return int(sel["run"].iloc[0]) if len(sel) else None


def _density_inputs(data, cands, cfg: StudyConfig, run: int):
    """One batch of two copies of ``run`` (original, flooded) padded to one candidate count,
    so one compiled call decides both, and the floors (``decide``'s ``min_*``) that give it
    the shapes of every window whatever window it is later cut at: ``(batch, recs, runs,
    one, flooded, both, floors)``."""
    batch, recs, runs, _ = density.subset(data, cands, [run, run])
    one = density.subset(data, cands, [run])[3]
    flooded = density.flood(one, cfg.density_factor, seed=cfg.main_seed)
    both = density.stack_copies(one, flooded)
    ev = run_inputs(batch, both).evidence
    floors = dict(min_windows=int(ev.valid.shape[1]), min_step=int(ev.traj_mask.shape[2]),
                  min_head=int(ev.head_mask.shape[2]))  # fmt: skip
    return batch, recs, runs, one, flooded, both, floors


def _compile_density(data, cands, cfg: StudyConfig) -> None:
    """Starts compiling the density table's decision in the background (``cands`` need only
    their shapes)."""
    run = _density_run(data, cfg)
    if run is not None:
        batch, _, _, _, _, both, floors = _density_inputs(data, cands, cfg, run)
        pipeline.compile_decisions(data, both, cfg.decision, batch=batch, ours=("ours",),
                                   **floors)  # fmt: skip


def _density(data, cands, scored, cfg: StudyConfig, tm) -> pd.DataFrame | None:
    """The density-immunity table for ``cfg.density_run`` at the main seed."""
    run = _density_run(data, cfg)
    if run is None:
        return None
    batch, recs, runs, one, flooded, both, floors = _density_inputs(data, cands, cfg, run)
    ours = scored[(scored["run"] == run) & (scored["policy"] == "ours")].sort_values("k")
    com = ours[ours["state"] == "COMMIT"]
    k_star = int(com["k"].iloc[0]) if len(com) else int(ours["k"].max())
    # Only windows up to our commit window: the pool is the one the decision saw.
    wm = np.asarray(batch.runs.window_mask).copy()
    wm[:, k_star:] = False
    rb = batch.runs
    batch = replace(batch, runs=replace(rb, window_mask=wm))
    w = pipeline.decide(data, both, cfg.decision, tm, label="density", progress=cfg.progress,
                        batch=batch, ours=("ours",), **floors)  # fmt: skip
    scored_both = pipeline.score(data, w, batch, recs, runs)
    frames = [scored_both[scored_both["run"] == r] for r in (0, 1)]
    rows = np.asarray(rb.submap)[0, :k_star]
    pools = [int(np.asarray(c.mask)[rows[rows >= 0]].sum()) for c in (one, flooded)]
    return density.density_table(frames[0], frames[1], k_star, pools[0], pools[1])


def run_study(cfg: StudyConfig, write_raw: bool = True) -> dict:
    """Runs the sweep and writes every table and figure under ``cfg.out``.

    Returns:
        The tables by name (also written as CSV/Markdown/LaTeX).
    """
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    tm = pipeline.Timings()
    t_start = time.perf_counter()
    seeds = list(range(cfg.seed0, cfg.seed0 + cfg.seeds))
    # The front-end's call compiles in the background while the later scenes are simulated
    # (``pipeline.prepare``); the decision programs need the candidates' shapes only, so they
    # compile in the background while the front-end registers, and the decisions wait for them.
    scenes = [get_scene(name) for name in cfg.scenes]
    fe = pipeline.frontend(scenes, cfg.frontend)

    def compile_ahead(data) -> None:
        shaped = no_candidates(data.batch.submaps.n, cfg.frontend.J)
        pipeline.compile_decisions(data, shaped, cfg.decision)
        if "three_rooms" in cfg.scenes:
            _compile_density(data, shaped, cfg)

    data, cands = pipeline.prepare(scenes, cfg.d_s, seeds, cfg.sim, tm, fe, cfg.progress,
                                   cfg.window, on_packed=compile_ahead)  # fmt: skip
    windows = pipeline.decide(data, cands, cfg.decision, tm, progress=cfg.progress)
    scored = pipeline.score(data, windows)
    dens = _density(data, cands, scored, cfg, tm) if "three_rooms" in cfg.scenes else None
    # Ablation of the congruence threshold: the paper's exact congruence (near-copies are not
    # a lattice) against our default, on the same candidates: the lane ``ours_strict``.
    strict = scored[scored["policy"] == "ours_strict"].assign(policy="ours")
    scored = scored[scored["policy"] != "ours_strict"].reset_index(drop=True)
    congruence = report.congruence_table(scored, strict, STRICT_IOU)
    t0 = time.perf_counter()
    if write_raw:
        raw = out / "raw"
        raw.mkdir(exist_ok=True)
        scored.drop(columns=["yaw"]).to_csv(
            raw / RAW,
            index=False,
            float_format="%.5g",
            compression={"method": "gzip", "mtime": 0},  # byte-identical reruns
        )
        if dens is not None:
            dens.to_csv(raw / "density_immunity.csv", index=False)
    paths = report.build_figures(scored, data, cands, out, cfg.main_seed) if cfg.figures else []
    tm.add("tables + figures", 0.0, time.perf_counter() - t0, f"{len(paths)} figures")
    tm.add("wall clock", 0.0, time.perf_counter() - t_start, "whole sweep, end to end")
    timings = tm.frame()
    timings = timings[timings["stage"] != "total"]
    tabs = report.build_tables(scored, out, cfg.main_seed, dens, timings)
    tables.write_table(congruence, out, "congruence")
    tabs["congruence"] = congruence
    (out / "sweep_config.json").write_text(
        json.dumps(
            {
                "scenes": cfg.scenes,
                "d_s": cfg.d_s,
                "seeds": seeds,
                "main_seed": cfg.main_seed,
                "density_run": cfg.density_run,
                "density_factor": cfg.density_factor,
            },
            indent=1,
        )
    )
    return tabs


class MergeError(ValueError):
    """Jobs that cannot make one study (``merge``); the message names them."""


def merge(job_dirs, out, main_seed: int = 0) -> dict:
    """Builds the tables from several jobs' raw outputs (a Hydra multirun)."""
    frames, dens = [], None
    for d in job_dirs:
        p = Path(d) / "raw" / RAW
        if p.exists():
            # room names stay names ("209", never 209.0 where a column also holds NaN)
            rooms = {"room": str, "true_room": str}
            try:
                frames.append(pd.read_csv(p, dtype=rooms).assign(_job=str(d)))
            except (ValueError, OSError, EOFError) as e:  # a damaged or truncated job file
                raise MergeError(f"merge: {p}: not a readable table ({e})") from e
        q = Path(d) / "raw" / "density_immunity.csv"
        if q.exists():
            dens = pd.read_csv(q)
    if not frames:
        raise FileNotFoundError(f"merge: no {RAW} under any of {list(map(str, job_dirs))}")
    scored = pd.concat(frames, ignore_index=True)
    key = ["scene", "trajectory", "d_s", "seed", "policy", "k"]
    found = jobs.repeated(scored, key)
    if found is not None:
        # two jobs decided the same window (a multirun over a setting, ``decision.b_min=3,4``,
        # not over scenes, seeds or d_s): one table of both would mix two settings
        first, holders = found
        raise MergeError(
            f"merge: {first['scene']}/{first['trajectory']} at d_s={first['d_s']:g}, seed "
            f"{first['seed']} is in {jobs.where(holders)}: jobs that ran the same runs with "
            "different settings are separate studies; merge jobs that split scenes, seeds or d_s"
        )
    scored = scored.drop(columns="_job")
    # Runs are numbered per job; make them unique before grouping.
    scored["run"] = scored.groupby(["scene", "trajectory", "d_s", "seed"]).ngroup()
    Path(out).mkdir(parents=True, exist_ok=True)
    return report.build_tables(scored, out, main_seed, dens)
