"""The study pipeline on the one data path: simulate -> windows -> register -> decide -> score.

Scenes are simulated into ``Recording``s (``sources.simulated``), cut into windows for every
``d_s``, packed and registered by the one batch path (``drive.register``, with the one
front-end driver ``frontend.driver.FrontEnd``), decided by the one decision layer
(``decision.runs``: ``vmap`` over runs of ``lax.scan`` of ``layer.update``) and scored by the
one scorer (``score.score_batch``). Ground truth enters only in ``score``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from mfcl_jax import se2
from mfcl_jax import windows as W
from mfcl_jax.decision import frame as decision_frame
from mfcl_jax.decision.lanes import COUNT_VARIANTS, OURS_VARIANTS
from mfcl_jax.decision.params import DecisionParams
from mfcl_jax.drive.register import register
from mfcl_jax.frontend.candidates import Candidates
from mfcl_jax.frontend.driver import FrontEnd
from mfcl_jax.score import pose_at, score_batch
from mfcl_jax.sim import SimParams
from mfcl_jax.sim.scenes import get_scene
from mfcl_jax.sources.simulated import simulate

__all__ = ["Timings", "StudyData", "frontend", "prepare", "compile_decisions", "decide", "score",
           "log", "CHUNK"]  # fmt: skip

CHUNK = 32  # submaps per front-end call


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
    """Everything simulated for a sweep.

    Attributes:
        batch: the ``WindowBatch`` of every run (scene x trajectory x d_s x seed).
        recordings: the ``Recording`` of each run (runs of one trajectory and seed at
            different ``d_s`` share one recording).
        runs: one row per run: scene, trajectory, d_s, seed, run, n_scans, n_windows, length_m.
        scenes: the ``Scene`` objects, by building index.
    """

    batch: W.WindowBatch
    recordings: list
    runs: pd.DataFrame
    scenes: list

    @property
    def floorplans(self) -> list:
        return [s.floorplan for s in self.scenes]

    def true_pose(self, run: int, k: int) -> np.ndarray:
        """True sensor pose at window ``k`` (1-based) of ``run`` (figures only)."""
        rec = self.recordings[run]
        t = self.batch.windows[run].t[k - 1]
        return pose_at(rec.truth.times, rec.truth.poses, [t])[0]

    def true_anchor(self, run: int) -> np.ndarray:
        """The hidden ``^B T_L`` of ``run`` (figures only)."""
        rec = self.recordings[run]
        Y = pose_at(rec.truth.times, rec.truth.poses, rec.seq.times[:1])[0]
        return np.asarray(se2.compose(Y, se2.inverse(rec.seq.odometry[0])), np.float64)


def log(msg: str, on: bool = True) -> None:
    if on:
        print(msg, file=sys.stderr, flush=True)


def frontend(scenes, params) -> FrontEnd:
    """The study's front-end: the plans of ``scenes`` (``Scene``s) in one shape bucket,
    ``CHUNK`` submaps per call."""
    return FrontEnd([s.floorplan for s in scenes], params, chunk=CHUNK)


def prepare(scenes, d_s, seeds, sim: SimParams, timings: Timings, fe: FrontEnd, progress=True,
            window=None, on_packed=None) -> tuple[StudyData, Candidates]:  # fmt: skip
    """Simulates every (scene, trajectory, seed), cuts windows for every ``d_s`` and registers
    them with ``fe`` (``frontend``) through the one batch path (``drive.register``).

    Runs are ordered scene, then trajectory, then ``d_s``, then seed. ``scenes``: names or
    ``Scene``s. The scenes are simulated one by one as the batch path asks for them, so the
    front-end's call compiles (for the first scene's point capacity) while the later scenes
    are simulated. ``on_packed(data)``: called with the ``StudyData`` once every window is
    packed, before the front-end runs (``drive.register``).
    """
    window = window or W.WindowParams()
    recs, rows, objs = [], [], []

    def groups():
        for b, scene in enumerate(scenes):
            scene = get_scene(scene) if isinstance(scene, str) else scene
            objs.append(scene)
            t0[0] = time.perf_counter()
            sims = simulate(scene, seeds=seeds, params=sim)
            by = {(r.meta["trajectory"], r.meta["seed"]): r for r in sims}
            todo = [(by[(traj, s)], traj, float(ds), s)
                    for traj in scene.trajectories for ds in d_s for s in seeds]  # fmt: skip
            for rec, traj, ds, s in todo:
                rows.append(dict(scene=scene.name, trajectory=traj, d_s=ds, seed=int(s),
                                 run=len(recs), n_scans=len(rec.seq),
                                 length_m=rec.meta["length_m"]))  # fmt: skip
                recs.append(rec)
            yield [(rec.seq, W.WindowParams(**{**window.__dict__, "d_s": ds}), b)
                   for rec, _, ds, _ in todo]  # fmt: skip

    def cut(group, wins) -> None:  # after each scene: its windows, its time
        name = objs[-1].name
        n0 = len(rows) - len(group)
        for row, w in zip(rows[n0:], wins, strict=True):
            row["n_windows"] = len(w)
        dt = time.perf_counter() - t0[0]
        n_sub = sum(len(w) for w in wins)
        timings.add(f"simulate {name}", 0.0, dt, f"{len(group)} runs, {n_sub} submaps")
        log(f"[sim] {name}: {len(group)} runs, {n_sub} submaps in {dt:.1f} s", progress)

    t0 = [0.0]
    c0, r0 = fe.compile_s, fe.run_s

    def packed(batch) -> None:
        t0[0] = time.perf_counter()  # the front-end's stage starts
        if on_packed is not None:
            on_packed(StudyData(batch, recs, _runs(rows), objs))

    reg = register(groups(), fe, on_cut=cut, on_packed=packed)
    n = reg.batch.submaps.n
    per = 1e3 * (fe.run_s - r0) / max(n, 1)
    wall = time.perf_counter() - t0[0]
    comp = fe.compile_s - c0
    timings.add("front-end", comp, wall - comp, f"{n} submaps, {per:.1f} ms/submap")
    log(f"[front-end] compile {comp:.1f} s, {per:.1f} ms/submap", progress)
    return StudyData(reg.batch, recs, _runs(rows), objs), reg.cands


def _runs(rows) -> pd.DataFrame:
    cols = ["scene", "trajectory", "d_s", "seed", "run", "n_scans", "n_windows", "length_m"]
    return pd.DataFrame(rows)[cols]


def compile_decisions(data: StudyData, cands: Candidates, params: DecisionParams, batch=None,
                      ours=COUNT_VARIANTS, **floors) -> None:  # fmt: skip
    """Starts compiling what ``decide`` with the same arguments will call, in the background
    (``decision.frame.compile_decisions``); ``cands`` need only their shapes."""
    decision_frame.compile_decisions(batch or data.batch, cands, data.floorplans, params,
                                     ours=ours, **floors)  # fmt: skip


def decide(
    data: StudyData,
    cands: Candidates,
    params: DecisionParams,
    timings: Timings,
    label="decision",
    progress=True,
    batch=None,
    ours=COUNT_VARIANTS,
    **floors,
) -> pd.DataFrame:
    """Every lane's decision (``ours`` and the baselines) at every window of every run, in
    one compiled call per capacity bucket; ``batch`` replaces ``data.batch`` (a subset);
    ``floors``: ``decision.frame.decide``'s."""
    batch = batch or data.batch
    df, tm = decision_frame.decide(batch, cands, data.floorplans, params, ours=ours, **floors)
    note = f"{batch.runs.n_runs} runs x {batch.runs.n_windows} windows, {tm['searches']} searches"
    timings.add(label, tm["compile_s"], tm["run_s"], note)
    log(f"[{label}] {note}: compile {tm['compile_s']:.1f} s, run {tm['run_s']:.1f} s", progress)
    return df[df["set"] == 0].drop(columns="set")


def score(data: StudyData, windows: pd.DataFrame, batch=None, recordings=None, runs=None):
    """Ground-truth errors and room names for every window row (``score.score_batch``).

    Baselines that have not committed carry no anchor; ours and its variants always report
    ``T*`` (scored, so figures can show it before the commit).
    """
    batch = batch or data.batch
    recordings = recordings or data.recordings
    runs = data.runs if runs is None else runs
    w = windows.copy()
    anchored = w["state"].eq("COMMIT") | w["policy"].isin(list(OURS_VARIANTS))
    for c in ("x", "y", "yaw_deg"):
        w.loc[~anchored, c] = np.nan
    s = score_batch(w, batch, recordings, rooms=True)
    s["yaw"] = np.deg2rad(s["yaw_deg"])
    meta = runs[["run", "scene", "trajectory", "d_s", "seed"]]
    return s.merge(meta, on="run", how="left")
