"""The one decision driver (batch mode): candidates of many runs -> every policy's decision
at every window.

Runs are evaluated in chunks of ``runs_per_call`` runs that together use at most
``buildings_per_call`` buildings: the chunk's ``DecisionMaps`` are stacked once per building
(not per run) and every call has the same padded shapes, so one compilation serves the whole
batch while memory stays bounded (a building's maps hold the gate labels and the two
verification fields of the certification). Host code only gathers, pads and turns the result
into a table; the streaming mode for a robot is ``decision.stream``.
"""

from __future__ import annotations

import time
from dataclasses import replace

import jax
import numpy as np
import pandas as pd

from mfcl_jax.decision import policies
from mfcl_jax.decision.evaluate import NO_RIVAL, batch_inputs, evaluate, policy_names, to_frame
from mfcl_jax.decision.maps import DecisionMaps, decision_maps, pad_maps
from mfcl_jax.decision.policies import OURS_VARIANTS
from mfcl_jax.decision.rivals import (
    DEFAULT_RIVALS,
    RIVAL_SLOTS,
    RivalParams,
    rival_fields,
    search_into,
)
from mfcl_jax.decision.state import COMMIT, DecisionParams

__all__ = ["building_maps", "chunks", "decide", "split_segments"]


def building_maps(floorplans, used, min_iou: float | None = None) -> dict[int, DecisionMaps]:
    """``DecisionMaps`` of the buildings ``used``, padded to one bucket (host arrays)."""
    kw = {} if min_iou is None else {"min_iou": min_iou}
    maps = {b: decision_maps(floorplans[b], **kw) for b in used}
    shape = tuple(int(max(np.asarray(m.label).shape[i] for m in maps.values())) for i in range(2))
    n_rooms = max(m.n_rooms for m in maps.values())
    n_mot = max(int(np.asarray(m.motions).shape[0]) for m in maps.values())
    n_off = max(int(np.asarray(m.offsets).shape[0]) for m in maps.values())
    out = {}
    for b, m in maps.items():
        m = pad_maps(m, shape, n_rooms, n_mot)
        off, om = np.asarray(m.offsets), np.asarray(m.offsets_mask)
        extra = n_off - off.shape[0]
        off = np.concatenate([off, np.zeros((extra, 2), off.dtype)])
        om = np.concatenate([om, np.zeros(extra, bool)])
        out[b] = DecisionMaps(
            m.origin, m.label, m.adjacency, off, om, m.generators, m.generators_mask,
            m.motions, m.motions_mask, m.sdf4, m.pen4, m.res,
        )  # fmt: skip
    return out


def chunks(run_building, runs_per_call: int, buildings_per_call: int, keys=None):
    """Run indices in chunks of at most ``runs_per_call`` runs and ``buildings_per_call``
    distinct buildings; runs with different ``keys`` (shape buckets) never share a chunk, and
    runs of one building stay together where possible."""
    rb = np.asarray(run_building)
    keys = np.zeros(len(rb), np.int64) if keys is None else np.asarray(keys)
    order = np.lexsort((rb, keys))
    out, cur, seen, key = [], [], set(), None
    for r in order:
        b = int(rb[r])
        full = len(cur) == runs_per_call or (b not in seen and len(seen) == buildings_per_call)
        if cur and (full or keys[r] != key):
            out.append(np.asarray(cur))
            cur, seen = [], set()
        cur.append(int(r))
        seen.add(b)
        key = keys[r]
    if cur:
        out.append(np.asarray(cur))
    return out


def _bucket(n, minimum, step=None):
    if step:
        return max(minimum, -(-int(n) // step) * step)
    return 1 << max(minimum.bit_length() - 1, (max(int(n), 1) - 1).bit_length())


def decide(
    batch,
    cands,
    floorplans,
    params: DecisionParams | list[DecisionParams] | None = None,
    ours=tuple(policies.OURS_VARIANTS),
    min_iou: float | None = None,
    runs_per_call: int = 8,
    buildings_per_call: int = 8,
    run_chunk: int = 8,
    progress=None,
    rival_params: RivalParams | None = DEFAULT_RIVALS,
    primary: str = "ours",
    primary_set: int = 0,
) -> tuple[pd.DataFrame, dict]:
    """Every policy's decision at every window of every run of a ``WindowBatch``.

    Args:
        batch: ``windows.WindowBatch`` (with its evidence samples; points not needed).
        cands: ``Candidates`` of ``batch.submaps`` (host).
        floorplans: ``Floorplan`` per building index.
        params: one ``DecisionParams`` or a list (a threshold-set axis that may vary only
            ``state.KNOBS``; no recompilation).
        ours: names of our variants to evaluate (baselines are always included).
        min_iou: room-congruence threshold override for the maps (an ablation).
        runs_per_call, buildings_per_call: chunk sizes (static: one compilation).
        run_chunk: runs per step of the sequential map inside a call.
        progress: optional callable ``progress(runs_done)``.
        rival_params: settings of the global search for rivals where ``primary`` (at threshold
            set ``primary_set``) is about to commit (``rivals``; None: no search). Every
            certifying policy then weighs the rivals found; the search prefixes are the
            primary's, which is what a robot running the primary would search.

    Returns:
        ``(frame, timing)``: one row per run x window x threshold set x policy (columns of
        ``evaluate.to_frame``, ``run`` indexing the batch's runs) and
        ``{"compile_s", "run_s", "search_s", "searches"}``.
    """
    params = params or DecisionParams()
    stacked = DecisionParams.stack(params if isinstance(params, list) else [params])
    var = policies.variants(ours)
    runs, stacked, var, n_bad = batch_inputs(cands, batch, stacked, var)
    R0, K0 = np.asarray(runs.window_mask).shape
    runs, pieces = split_segments(runs, np.asarray(batch.runs.traj_seg))
    rb = np.asarray(batch.run_building)[pieces[:, 0]]
    runs_per_call = max(1, min(runs_per_call, rb.shape[0]))
    maps = building_maps(floorplans, sorted(set(rb.tolist())), min_iou)
    any_map = next(iter(maps.values()))
    # Shape buckets: runs are padded to their own bucket of windows (multiples of 16) and
    # keyframes (powers of two), not to the longest run of the batch.
    k_b = np.asarray([_bucket(n, 16, 16) for n in np.asarray(runs.window_mask).sum(1)])
    t_b = np.asarray([_bucket(n, 128) for n in np.asarray(runs.traj_mask).sum(1)])
    compiled, tm = {}, {"compile_s": 0.0, "run_s": 0.0, "search_s": 0.0, "searches": 0}
    R, K = rb.shape[0], int(np.asarray(runs.window_mask).shape[1])

    def run_chunks(runs, todo):
        parts = []
        for idx in chunks(
            rb[todo], runs_per_call, buildings_per_call, keys=k_b[todo] * 65536 + t_b[todo]
        ):
            idx = todo[idx]
            kb, tb = int(k_b[idx[0]]), int(t_b[idx[0]])
            sub = jax.tree.map(lambda a, i=idx: _pad_rows(np.asarray(a)[i], runs_per_call), runs)
            sub = _trim(sub, kb, tb)
            used = list(dict.fromkeys(rb[idx].tolist()))
            stack = [maps[b] for b in used] + [any_map] * (buildings_per_call - len(used))
            mp = jax.tree.map(lambda *xs: np.stack(xs), *stack)
            local = np.asarray([used.index(b) for b in rb[idx]], np.int32)
            local = _pad_rows(local, runs_per_call)
            if (kb, tb) not in compiled:
                t0 = time.perf_counter()
                lowered = evaluate.lower(sub, mp, local, stacked, var, run_chunk=run_chunk)
                compiled[kb, tb] = lowered.compile()
                tm["compile_s"] += time.perf_counter() - t0
            t0 = time.perf_counter()
            dec = jax.block_until_ready(compiled[kb, tb](sub, mp, local, stacked, var))
            tm["run_s"] += time.perf_counter() - t0
            n = len(idx)
            dec = jax.tree.map(lambda a: _pad_axis1(np.asarray(a)[:n], K), dec)  # noqa: B023
            parts.append((idx, dec))
            if progress is not None:
                progress(sum(len(i) for i, _ in parts))
        return parts

    dec = _scatter(run_chunks(runs, np.arange(R)), R)
    if rival_params is not None and primary in ours and OURS_VARIANTS[primary][2]:
        v0 = list(ours).index(primary)
        dec, runs = _with_rivals(dec, runs, rb, floorplans, run_chunks, primary_set, v0,
                                 rival_params, tm)  # fmt: skip
    dec = _merge_segments(dec, pieces, R0, K0)
    frame = to_frame(dec, policy_names(ours), batch.runs.window_mask, n_bad)
    return frame, tm


def _with_rivals(dec, runs, rb, floorplans, run_chunks, s0, v0, rp: RivalParams, tm):
    """The global search where the primary policy is about to commit, then the runs again.

    Where the commit machine of policy ``v0`` at threshold set ``s0`` enters COMMIT at a prefix
    not searched yet (and the run has searches left), the path up to that prefix is searched
    (``rivals``); the placements found are the run's rivals from that prefix on, and the run
    is decided again (every policy and set: they all certify against the same rivals). This
    repeats until no run enters COMMIT at an unsearched prefix, as ``stream`` does online.
    """
    R = rb.shape[0]
    riv = np.zeros((R, RIVAL_SLOTS, 3), np.float32)
    riv_k = np.full((R, RIVAL_SLOTS), NO_RIVAL, np.int32)
    last = np.full(R, -1)
    n_done = np.zeros(R, np.int64)
    fields: dict = {}
    ts, n_search = 0.0, 0
    wm = np.asarray(runs.window_mask)
    while True:  # ends: every pass searches at least once, at most max_searches per run
        st = np.asarray(dec.state)[:, :, s0, v0] == COMMIT  # (R, K)
        entry = st & ~np.pad(st, ((0, 0), (1, 0)))[:, :-1] & wm
        todo = []
        for r in np.flatnonzero(n_done < rp.max_searches):
            ks = np.flatnonzero(entry[r] & (np.arange(st.shape[1]) > last[r]))
            if len(ks) == 0:
                continue
            k = int(ks[0])
            b = int(rb[r])
            if b not in fields:
                fields[b] = rival_fields(floorplans[b], rp)
            t0 = time.perf_counter()
            ev = (runs.ev_points[r], runs.ev_origins[r], runs.ev_mask[r])
            search_into(riv[r], riv_k[r], int(n_done[r]), ev, runs.X[r], k, fields[b], rp)
            ts += time.perf_counter() - t0
            n_search += 1
            last[r], n_done[r] = k, n_done[r] + 1
            todo.append(r)
        if not todo:
            break
        runs = replace(runs, rivals=riv, rivals_k=riv_k)
        todo = np.asarray(todo)
        for idx, d in run_chunks(runs, todo):
            for full, part in zip(jax.tree.leaves(dec), jax.tree.leaves(d), strict=True):
                full[idx] = part
    tm["search_s"], tm["searches"] = ts, n_search
    return dec, runs


def split_segments(runs, traj_seg) -> tuple[object, np.ndarray]:
    """Every odometry segment (``traj_seg (R, T)``, ``Windows.segments``) of every run as a run
    of its own.

    Poses before and after an odometry jump (a restart) are in incommensurable frames, so the
    layer starts over after one: the windows of a segment are decided from that segment's
    windows and trajectory only, and the commit machine begins afresh.

    Returns:
        ``(runs, pieces)``: the split ``RunInputs`` and ``pieces (R', 3)`` = (source run,
        first window, window count) per split run. Without a jump, ``runs`` unchanged.
    """
    wm, tm = np.asarray(runs.window_mask), np.asarray(runs.traj_mask)
    ws = np.asarray(runs.window_start)
    R, K = wm.shape
    T = tm.shape[1]
    pieces, spans = [], []
    for r in range(R):
        nk, nt = int(wm[r].sum()), int(tm[r].sum())
        seg = np.asarray(traj_seg[r, :nt])  # 0 at the run's start (Windows.segments)
        if nk == 0 or nt == 0 or seg[-1] == 0:
            pieces.append((r, 0, nk))
            spans.append((0, T))
            continue
        wseg = seg[ws[r, :nk]]
        for sid in np.unique(wseg):
            ks, ts = np.flatnonzero(wseg == sid), np.flatnonzero(seg == sid)
            pieces.append((r, int(ks[0]), len(ks)))
            spans.append((int(ts[0]), int(ts[-1]) + 1))
    pieces = np.asarray(pieces, np.int64).reshape(-1, 3)
    if len(pieces) == R:
        return runs, pieces
    out = {}
    for name in type(runs).__dataclass_fields__:
        if getattr(runs, name) is None:
            out[name] = None
            continue
        a = np.asarray(getattr(runs, name))
        b = np.zeros((len(pieces), *a.shape[1:]), a.dtype)
        for i, ((r, w0, n), (t0, t1)) in enumerate(zip(pieces, spans, strict=True)):
            if name in ("traj", "traj_mask"):
                b[i, : t1 - t0] = a[r, t0:t1]
                if name == "traj":
                    b[i, t1 - t0 :] = a[r, t1 - 1]
            elif name in ("rivals", "rivals_k"):  # per run, not per window
                b[i] = a[r]
                if name == "rivals_k":
                    b[i] = np.where(a[r] == NO_RIVAL, NO_RIVAL, np.maximum(a[r] - w0, 0))
            else:
                b[i, :n] = a[r, w0 : w0 + n]
                if name in ("window_start", "window_end"):
                    b[i, :n] -= t0
        out[name] = b
    return type(runs)(**out), pieces


def _merge_segments(dec, pieces: np.ndarray, R: int, K: int):
    """Decisions of split runs (``split_segments``) back into ``(R, K, ...)`` run order."""
    if len(pieces) == R and np.all(pieces[:, 1] == 0):
        return dec

    def merge(a):
        a = np.asarray(a)
        out = np.zeros((R, K, *a.shape[2:]), a.dtype)
        for i, (r, w0, n) in enumerate(pieces):
            out[r, w0 : w0 + n] = a[i, :n]
        return out

    return jax.tree.map(merge, dec)


def _trim(runs, kb: int, tb: int):
    """``RunInputs`` cut (or padded) to ``kb`` windows and ``tb`` keyframes."""

    def fit(a, axis, size):
        a = np.asarray(a)
        if a.shape[axis] >= size:
            return np.take(a, np.arange(size), axis=axis)
        pad = [(0, 0)] * a.ndim
        pad[axis] = (0, size - a.shape[axis])
        return np.pad(a, pad)

    per_window = ("H", "score", "mask", "window_start", "window_end", "window_mask", "X",
                  "ev_points", "ev_origins", "ev_mask")  # fmt: skip
    kw = {f: fit(getattr(runs, f), 1, kb) for f in per_window}
    kw.update(traj=fit(runs.traj, 1, tb), traj_mask=fit(runs.traj_mask, 1, tb))
    kw.update(rivals=runs.rivals, rivals_k=runs.rivals_k)
    return type(runs)(**kw)


def _pad_axis1(a: np.ndarray, n: int) -> np.ndarray:
    """Fits axis 1 (windows) of a chunk's decisions to the batch's window count."""
    if a.ndim < 2 or a.shape[1] == n:
        return a
    if a.shape[1] > n:
        return a[:, :n]
    pad = [(0, 0)] * a.ndim
    pad[1] = (0, n - a.shape[1])
    return np.pad(a, pad)


def _pad_rows(a: np.ndarray, n: int) -> np.ndarray:
    if a.shape[0] >= n:
        return a
    return np.concatenate([a, np.repeat(a[-1:], n - a.shape[0], axis=0)])


def _scatter(parts, R):
    """Chunk results back into run order ``(R, ...)``."""
    leaves, tree = jax.tree.flatten(parts[0][1])
    out = [np.zeros((R, *a.shape[1:]), a.dtype) for a in leaves]
    for idx, dec in parts:
        for o, d in zip(out, jax.tree.leaves(dec), strict=True):
            o[idx] = d
    return jax.tree.unflatten(tree, out)
