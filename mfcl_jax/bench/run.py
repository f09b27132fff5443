"""The benchmark pipeline: recordings -> windows -> front-end -> labels -> decisions -> scores.

Runs are processed group by group (a family, or a fault axis): a group is cut, packed and
registered by the one batch path (``drive.register``), and its scans and submap points live
only while its front-end pass, its labels and the particle filter run; what is kept (odometry,
windows, candidates, labels, ground truth) is small. Then every run of every group is decided
in one compiled call (all policies, all threshold sets of the risk-coverage sweep) and scored
by the one scorer. Ground truth enters only through ``mfcl_jax.score``.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np
import pandas as pd

from mfcl_jax import windows as W
from mfcl_jax.bench.config import BenchmarkConfig, validate
from mfcl_jax.decision.params import DecisionParams
from mfcl_jax.sources import Recording, ScanSequence

__all__ = ["KNOB_SETS", "DEFAULT_SET", "Collected", "collect", "decide_and_score", "window_metres"]

# Threshold sets of the risk-coverage sweep: every policy reads its own knob from the set
# (ours and its ablations: the floors b_min / delta_min; confidence: its ratio; support: its
# ratio). Set DEFAULT_SET holds the defaults, used by every headline table.
KNOB_SETS = (
    dict(b_min=2, delta_min=1, cert_margin=0.03, confidence_ratio=1.05, support_ratio=1.1),
    dict(b_min=3, delta_min=2, cert_margin=0.05, confidence_ratio=1.2, support_ratio=1.5),
    dict(b_min=3, delta_min=2, cert_margin=0.08, confidence_ratio=1.4, support_ratio=2.0),
    dict(b_min=4, delta_min=3, cert_margin=0.08, confidence_ratio=1.7, support_ratio=3.0),
    dict(b_min=5, delta_min=4, cert_margin=0.10, confidence_ratio=2.0, support_ratio=4.0),
    dict(b_min=6, delta_min=5, cert_margin=0.12, confidence_ratio=2.5, support_ratio=6.0),
    dict(b_min=8, delta_min=6, cert_margin=0.15, confidence_ratio=3.0, support_ratio=8.0),
)
DEFAULT_SET = 1


def _label_version() -> str:
    """Cached labels are reused only while the labelling code is unchanged."""
    from mfcl_jax.floorplan import passages, raster
    from mfcl_jax.frontend import path_fields, path_search, placements
    from mfcl_jax.score import identifiability

    h = hashlib.sha1()
    for mod in (identifiability, passages, path_search, path_fields, placements, raster):
        h.update(Path(mod.__file__).read_bytes())
    return h.hexdigest()[:12]


def _log(cfg, msg):
    if cfg.progress:
        print(f"[benchmark] {msg}", file=sys.stderr, flush=True)


@dataclass
class Collected:
    """Everything kept of the runs after their group's heavy work (no scans, no points)."""

    recordings: list = field(default_factory=list)  # light: odometry, times, truth, meta
    batches: list = field(default_factory=list)  # WindowBatch without points, per group
    candidates: list = field(default_factory=list)  # Candidates per group
    floorplans: list = field(default_factory=list)  # by building index
    building_of: dict = field(default_factory=dict)  # id(floorplan) -> building index
    labels: list = field(default_factory=list)  # RunLabel per run
    mcl: list = field(default_factory=list)  # per-group MCL decision frames
    nominal_labels: dict = field(default_factory=dict)  # (family, seed, walk) -> RunLabel
    timings: dict = field(default_factory=dict)  # stage -> seconds
    n_submaps: int = 0

    def tick(self, stage: str, seconds: float) -> None:
        self.timings[stage] = self.timings.get(stage, 0.0) + seconds


def _light(rec: Recording) -> Recording:
    seq = rec.seq
    empty = np.zeros((0, 2))
    light = ScanSequence(seq.times, [empty] * len(seq), seq.odometry, seq.source)
    return Recording(rec.name, rec.floorplan, light, rec.truth, rec.meta)


# Faults that change neither the building nor the walk, only the sensor or the odometry: the
# run's label is its nominal twin's (same true path, same walls; what the robot saw differs by
# noise only), so it is computed once.
SAME_GEOMETRY = ("drift", "yaw_drift", "dropout", "range_noise", "restart", "latency")


def _digest(rec: Recording) -> str:
    h = hashlib.sha1(_label_version().encode())
    for a in (rec.seq.times, rec.seq.odometry, rec.truth.poses, rec.floorplan.walls):
        h.update(np.ascontiguousarray(a, np.float64).tobytes())
    h.update(np.float64(sum(float(np.nansum(s)) for s in rec.seq.scans)).tobytes())
    return h.hexdigest()[:20]


def _walk_key(rec: Recording) -> tuple:
    return (rec.meta.get("family"), rec.meta.get("seed"), rec.meta.get("walk"))


def _labels(recs, wins, cfg, col: Collected):
    from mfcl_jax.frontend import path_search as ps
    from mfcl_jax.score.identifiability import RunLabel, label_runs

    cache = Path(cfg.cache).expanduser() / "labels" if cfg.cache else None
    out, todo = [None] * len(recs), []
    for i, r in enumerate(recs):
        twin = col.nominal_labels.get(_walk_key(r))
        if r.meta.get("fault", "") in SAME_GEOMETRY and twin is not None:
            out[i] = twin
            continue
        f = cache / f"{_digest(r)}.json" if cache else None
        if f is not None and f.is_file():
            d = json.loads(f.read_text())
            d["identifiable_k"] = np.asarray(d["identifiable_k"], bool)
            d["alternative"] = tuple(d["alternative"]) if d["alternative"] else None
            out[i] = RunLabel(**d)
            if r.meta.get("fault", "") == "":
                col.nominal_labels[_walk_key(r)] = out[i]
        else:
            todo.append(i)
    fields = {}

    def fields_of(rec):
        key = id(rec.floorplan)
        if key not in fields:
            r = rec.floorplan.rasterize()
            shape = tuple(-(-n // 128) * 128 for n in r.shape)  # few buckets: few compiles
            fields[key] = ps.plan_fields(r, shape=shape)
        return fields[key]

    if todo:
        labs = label_runs([recs[i] for i in todo], [wins[i] for i in todo], fields_of)
        for i, lab in zip(todo, labs, strict=True):
            if recs[i].meta.get("fault", "") == "":
                col.nominal_labels[_walk_key(recs[i])] = lab
            out[i] = lab
            if cache is not None:
                cache.mkdir(parents=True, exist_ok=True)
                d = asdict(lab)
                d["identifiable_k"] = lab.identifiable_k.astype(int).tolist()
                (cache / f"{_digest(recs[i])}.json").write_text(json.dumps(d))
    return [_storey_label(r, lab) for r, lab in zip(recs, out, strict=True)]


def _storey_label(rec: Recording, lab):
    """A walk on a storey congruent to another (a tower's typical floor) is not identifiable,
    whatever its path: the place is, the storey never is."""
    if not rec.meta.get("congruent"):
        return lab
    k = np.zeros_like(np.asarray(lab.identifiable_k, bool))
    return replace(lab, identifiable=False, oracle_k=None, identifiable_k=k)


def _group(recs, cfg, fe, col: Collected, mcl_runner=None) -> None:
    """Front-end pass (``drive.register``), labels and the filter peer for one group of
    recordings."""
    from mfcl_jax.drive.register import register

    wp = W.WindowParams(d_s=cfg.d_s)
    bidx = col.building_of  # across groups: a plan shared by many runs is one building
    for r in recs:
        if id(r.floorplan) not in bidx:  # col.floorplans keeps it alive: ids stay unique
            bidx[id(r.floorplan)] = fe.add(r.floorplan)
            col.floorplans.append(r.floorplan)
    t0 = time.perf_counter()
    c0, r0 = fe.compile_s, fe.run_s
    cut_s = []
    # one capacity for every group: one front-end compilation per plan bucket
    reg = register([[(r.seq, wp, bidx[id(r.floorplan)]) for r in recs]], fe, capacity=wp.capacity,
                   on_cut=lambda *_: cut_s.append(time.perf_counter() - t0))  # fmt: skip
    col.tick("windows", cut_s[0])
    col.tick("front-end compile", fe.compile_s - c0)
    col.tick("front-end run", fe.run_s - r0)
    wb, wins = reg.batch, reg.windows
    col.n_submaps += int(wb.submaps.n)
    t0 = time.perf_counter()
    col.labels += _labels(recs, wins, cfg, col)
    col.tick("labels", time.perf_counter() - t0)
    if mcl_runner is not None:
        t0 = time.perf_counter()
        col.mcl.append(mcl_runner(recs, wins, len(col.recordings)))
        col.tick("mcl", time.perf_counter() - t0)
    col.batches.append(W.concat([wb]))
    col.candidates.append(reg.cands)
    col.recordings += [_light(r) for r in recs]


def collect(cfg: BenchmarkConfig, groups, mcl_runner=None) -> Collected:
    """Runs every group's heavy stages; ``groups`` yields ``(name, list of Recording)``."""
    from mfcl_jax.frontend.driver import FrontEnd

    cfg = validate(cfg)
    fe = FrontEnd(multiple=256)  # coarse shape buckets: few compilations for many buildings
    col = Collected()
    for name, make in groups:
        t0 = time.perf_counter()
        recs = make()
        col.tick("recordings", time.perf_counter() - t0)
        if not recs:
            continue
        _group(recs, cfg, fe, col, mcl_runner)
        _log(
            cfg,
            f"{name}: {len(recs)} runs done ({len(col.recordings)} runs, {col.n_submaps} submaps)",
        )
    return col


def window_metres(odometry, w) -> np.ndarray:
    """``(K,)`` metres travelled by the end of each window of ``w`` (``Windows``): the path
    length of the input odometry ``odometry (T, 3)`` over the run's keyframes, from its first
    keyframe to the window's last one; the distance the windows are cut by, an odometry
    quantity (no ground truth). Across an odometry jump (a restart) it runs on from the run's
    start: the jump's step counts nothing."""
    raw = np.asarray(odometry, np.float64)[np.asarray(w.keyframes)]
    if len(w) == 0:
        return np.zeros(0)
    return W.travelled(raw, w.segments)[np.asarray(w.bounds)[:, 1]]


def _metres_at(recordings, batch, run, k) -> np.ndarray:
    """Metres travelled (``window_metres``) at window ``k`` (1-based) of each row's ``run``."""
    per_run = [window_metres(r.seq.odometry, w) for r, w in zip(recordings, batch.windows,
                                                                strict=True)]  # fmt: skip
    K = max([len(m) for m in per_run] + [1])
    M = np.full((len(per_run), K + 1), np.nan)
    for i, m in enumerate(per_run):
        M[i, 1 : len(m) + 1] = m
    k = np.asarray(k, np.int64)
    return M[np.asarray(run, np.int64), np.where((k >= 1) & (k <= K), k, 0)]


def decide_and_score(col: Collected, cfg: BenchmarkConfig, ours) -> pd.DataFrame:
    """Every policy of ``ours`` (+ baselines) at every window and threshold set, scored.

    Returns:
        One row per run x window x set x policy with the scorer's columns, ``metres`` (the
        odometric distance travelled by the window's end, ``window_metres``: the same for every
        policy, the particle filter's rows included) and the run's meta.
    """
    from mfcl_jax.decision.frame import decide
    from mfcl_jax.frontend.candidates import Candidates
    from mfcl_jax.score import score_batch

    batch = W.concat(col.batches)
    cands = Candidates(
        *(np.concatenate([getattr(c, f.name) for c in col.candidates]) for f in fields(Candidates))
    )
    params = [DecisionParams().replace(**k) for k in KNOB_SETS]
    t0 = time.perf_counter()
    n_runs, said = batch.runs.n_runs, [t0]

    def progress(done: int) -> None:  # the longest stage: a line every 30 s and at the end
        now = time.perf_counter()
        if done >= n_runs or now - said[0] >= 30.0:
            said[0] = now
            _log(cfg, f"decisions: {done} of {n_runs} runs decided ({now - t0:.0f} s)")

    # each size class of building apart: a small plan's searches do not pay for the largest
    frame, tm = decide(batch, cands, col.floorplans, params, ours=tuple(ours),
                       primary_set=DEFAULT_SET, size_classes=True,
                       progress=progress)  # fmt: skip
    col.tick("decision compile", tm["compile_s"])
    col.tick("decision run", tm["run_s"])
    parts = [frame, *col.mcl]
    frame = pd.concat(parts, ignore_index=True) if col.mcl else frame
    # Fault runs enter only the fault tables, which read the default thresholds: the other
    # threshold sets (the risk-coverage sweep, nominal runs only) are not scored for them.
    fault = np.asarray([bool(r.meta.get("fault", "")) for r in col.recordings])
    frame = frame[~fault[frame["run"].to_numpy()] | (frame["set"].to_numpy() == DEFAULT_SET)]
    scored = score_batch(frame, batch, col.recordings, rooms=False)
    scored["metres"] = _metres_at(col.recordings, batch, scored["run"], scored["k"])
    col.tick("score", time.perf_counter() - t0 - tm["compile_s"] - tm["run_s"])
    meta = pd.DataFrame([dict(run=i, name=r.name, **r.meta) for i, r in enumerate(col.recordings)])
    return scored.merge(meta, on="run", how="left")
