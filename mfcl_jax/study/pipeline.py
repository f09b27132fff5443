"""The study pipeline: simulate -> register -> decide -> score, each stage one compiled call.

All buildings, trajectories, scales and seeds go through the front-end in ONE jitted call
(features of every building padded to one shape bucket; each submap carries its building's
index) and through the decision layer in ONE jitted call (per-run gate maps padded to one
bucket). Host code only pads, stacks and turns results into tables. Ground truth enters only
in ``score``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from mfcl_jax.batch import Candidates, RunBatch, SubmapBatch, Truth, concat, pad_submaps
from mfcl_jax.decision.evaluate import batch_inputs, evaluate, to_frame
from mfcl_jax.decision.gate import GateMaps, gate_maps, pad_maps
from mfcl_jax.decision.state import DecisionParams
from mfcl_jax.evaluate import metrics
from mfcl_jax.floorplan.scenes import get_scene
from mfcl_jax.frontend import registry
from mfcl_jax.sim import SimParams, simulate

__all__ = [
    "Timings",
    "StudyData",
    "prepare",
    "register_all",
    "compile_and_run",
    "decide",
    "score",
    "CHUNK",
]

CHUNK = 32  # submaps per front-end chunk (lax.map): bounds memory, not a Python loop


@dataclass
class Timings:
    """Wall-clock seconds per stage, compile apart from run."""

    rows: list = field(default_factory=list)

    def add(self, stage: str, compile_s: float, run_s: float, note: str = "") -> None:
        self.rows.append({"stage": stage, "compile_s": compile_s, "run_s": run_s, "note": note})

    def frame(self) -> pd.DataFrame:
        df = pd.DataFrame(self.rows, columns=["stage", "compile_s", "run_s", "note"])
        total = {"stage": "total", "compile_s": df["compile_s"].sum(), "run_s": df["run_s"].sum()}
        return pd.concat([df, pd.DataFrame([total | {"note": ""}])], ignore_index=True)


@dataclass
class StudyData:
    """Everything simulated for a sweep, concatenated over buildings."""

    submaps: SubmapBatch
    runs_batch: RunBatch
    truth: Truth
    runs: pd.DataFrame  # scene, trajectory, d_s, seed, run (global), ...
    scene_of_submap: np.ndarray  # (N,) building index of each submap
    scenes: list  # Scene objects, in building-index order


def log(msg: str, on: bool = True) -> None:
    if on:
        print(msg, file=sys.stderr, flush=True)


def prepare(scenes, d_s, seeds, sim: SimParams, timings: Timings, progress=True) -> StudyData:
    """Simulates every (scene, trajectory, d_s, seed) and stacks them into one batch."""
    parts, tables, objs = [], [], []
    for name in scenes:
        scene = get_scene(name)
        t0 = time.perf_counter()
        s = simulate(scene, d_s_values=d_s, seeds=seeds, params=sim)
        dt = time.perf_counter() - t0
        timings.add(f"simulate {name}", 0.0, dt, f"{len(s.runs)} runs, {s.submaps.n} submaps")
        log(f"[sim] {name}: {len(s.runs)} runs, {s.submaps.n} submaps in {dt:.1f} s", progress)
        parts.append((s.submaps, s.runs_batch, s.truth))
        tables.append(s.runs)
        objs.append(scene)
    sub, runs, truth, run_off, sub_off = concat(parts)
    frames = []
    scene_of = np.zeros(sub.n, np.int32)
    for i, (tab, ro, so) in enumerate(zip(tables, run_off, sub_off, strict=True)):
        tab = tab.copy()
        tab["run"] = tab["run"] + ro
        frames.append(tab)
        n_i = parts[i][0].n
        scene_of[so : so + n_i] = i
    return StudyData(sub, runs, truth, pd.concat(frames, ignore_index=True), scene_of, objs)


def _chunked_register(params):
    """A jitted ``(submaps, building index, stacked features) -> Candidates`` for any mix."""

    def one(points, origins, mask, b, feats):
        f = jax.tree.map(lambda a: a[b], feats)
        sub = SubmapBatch(
            points[None],
            origins[None],
            mask[None],
            jnp.zeros((1, 3)),
            jnp.zeros(1, jnp.int32),
            jnp.zeros(1, jnp.int32),
            jnp.zeros(1),
            jnp.zeros(1, jnp.int32),
        )
        c = registry.register(sub, f, params)
        return jax.tree.map(lambda a: a[0], c)

    def run(points, origins, mask, b, feats):
        n = points.shape[0]
        xs = (points, origins, mask, b)
        xs = jax.tree.map(lambda a: a.reshape(n // CHUNK, CHUNK, *a.shape[1:]), xs)
        out = jax.lax.map(lambda x: jax.vmap(one, in_axes=(0, 0, 0, 0, None))(*x, feats), xs)
        return jax.tree.map(lambda a: a.reshape(n, *a.shape[2:]), out)

    return jax.jit(run)


def register_all(data: StudyData, params, timings: Timings, progress=True) -> Candidates:
    """Runs the front-end on every submap of the study in one compiled call."""
    feats = registry.common_features([s.floorplan for s in data.scenes], params)
    feats = jax.tree.map(lambda *xs: jnp.stack(xs), *feats)
    sub = registry.sanitize_submaps(jax.tree.map(np.asarray, data.submaps))
    n = sub.n
    n_pad = -(-n // CHUNK) * CHUNK
    sub = pad_submaps(sub, n=n_pad)
    b = np.zeros(n_pad, np.int32)
    b[:n] = data.scene_of_submap
    args = (sub.points, sub.origins, sub.mask, b, feats)
    cands, tr = compile_and_run(
        _chunked_register(params), args, timings, "front-end", f"{n} submaps", progress
    )
    per = 1e3 * tr / max(n, 1)
    timings.rows[-1]["note"] = f"{n} submaps, {per:.1f} ms/submap"
    log(f"[front-end] {per:.1f} ms/submap", progress)
    return jax.tree.map(lambda a: np.asarray(a)[:n], cands)


def compile_and_run(fn, args, timings: Timings, label: str, note: str, progress=True):
    """Compiles ``fn`` ahead of time for ``args``, runs it once, and records both times.

    Returns:
        ``(result, run seconds)``.
    """
    t0 = time.perf_counter()
    compiled = fn.lower(*args).compile()
    tc = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = jax.block_until_ready(compiled(*args))
    tr = time.perf_counter() - t0
    timings.add(label, tc, tr, note)
    log(f"[{label}] {note}: compile {tc:.1f} s, run {tr:.1f} s", progress)
    return out, tr


def run_maps(data: StudyData, min_iou: float | None = None) -> GateMaps:
    """Gate maps per run, padded to one bucket and stacked ``(R, ...)``."""
    kw = {} if min_iou is None else {"min_iou": min_iou}
    maps = [gate_maps(s.floorplan, **kw) for s in data.scenes]
    shape = tuple(int(max(np.asarray(m.label).shape[i] for m in maps)) for i in range(2))
    n_rooms = max(m.n_rooms for m in maps)
    maps = [pad_maps(m, shape, n_rooms) for m in maps]
    scene_idx = {s.name: i for i, s in enumerate(data.scenes)}
    per_run = data.runs.sort_values("run")["scene"].map(scene_idx).to_numpy()
    return jax.tree.map(lambda *xs: np.stack(xs)[per_run], *maps)


def decide(
    data: StudyData,
    cands: Candidates,
    params: DecisionParams,
    timings: Timings,
    label="decision",
    progress=True,
    min_iou: float | None = None,
) -> pd.DataFrame:
    """Every policy's decision at every window of every run, in one compiled call.

    ``min_iou`` overrides the room-congruence threshold of the gate maps (an ablation).
    """
    runs_batch = data.runs_batch
    maps = run_maps(data, min_iou)
    args, n_bad = batch_inputs(cands, data.submaps, runs_batch, maps, params)
    note = f"{runs_batch.n_runs} runs x {runs_batch.n_windows} windows"
    dec, _ = compile_and_run(evaluate, args, timings, label, note, progress)
    df = to_frame(dec, window_mask=runs_batch.window_mask, n_bad=n_bad)
    df = df[df["set"] == 0].drop(columns="set")
    meta = data.runs[["run", "scene", "trajectory", "d_s", "seed"]]
    return df.merge(meta, on="run", how="left")


def score(data: StudyData, windows: pd.DataFrame) -> pd.DataFrame:
    """Adds ground-truth errors and room correctness to every window row."""
    w = windows.copy()
    w["yaw"] = np.deg2rad(w["yaw_deg"])
    anchored = w["state"].eq("COMMIT") | w["policy"].isin(
        ["ours", "no_probe", "consensus_only", "ours_b2_d1", "ours_b4_d2"]
    )
    for c in ("x", "y", "yaw"):
        w.loc[~anchored, c] = np.nan
    fps = {s.name: s.floorplan for s in data.scenes}
    return metrics.score_windows(w, data.runs_batch, data.submaps, data.truth, fps)
