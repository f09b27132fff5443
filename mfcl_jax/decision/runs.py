"""Many runs at once: ``vmap`` over runs of ``lax.scan(layer.update)``.

The host lays every run's windows out as ``WindowEvidence`` of shape ``(R, K, ...)``
(``inputs.run_inputs``), pads runs into chunks that share capacities (``Caps``) and at most
``buildings_per_call`` buildings, and calls one compiled function per capacity bucket (and,
where asked, per building size class: ``size_class``). The decision of every window is made
once, by the same ``update`` a robot calls."""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, replace
from functools import partial

import jax
import numpy as np

from mfcl_jax.background import Pending
from mfcl_jax.decision import layer, rivals
from mfcl_jax.decision.history import Caps
from mfcl_jax.decision.inputs import RunInputs
from mfcl_jax.decision.lanes import Lanes, LaneSpec
from mfcl_jax.decision.maps import decision_maps, stack_maps
from mfcl_jax.decision.params import DecisionParams

__all__ = ["Buildings", "stack_buildings", "size_class", "scan_runs", "compile_runs",
           "decide_runs", "wait_compiled", "chunks"]  # fmt: skip


@dataclass(frozen=True)
class Buildings:
    """Every building's decision maps (and rival fields) padded to one grid, ``(B, ...)``."""

    maps: object
    fields: object  # the plan's search fields (rivals.stack_fields)
    n_img: int


def stack_buildings(floorplans, spec: LaneSpec, rival_params=rivals.DEFAULT_RIVALS) -> Buildings:
    """``Buildings`` of ``floorplans`` for the lanes of ``spec`` (``rivals.RivalParams``)."""
    maps = stack_maps([decision_maps(fp, min_iou=spec.min_iou) for fp in floorplans])
    # the fields serve every lane (the drift check of a commit); the image size, the search
    n_img = rivals.image_size(floorplans, rival_params) if spec.searches else 0
    return Buildings(maps, rivals.stack_fields(floorplans, rival_params), n_img)


def chunks(run_building, runs_per_call: int, buildings_per_call: int, keys=None):
    """Run indices in chunks of at most ``runs_per_call`` runs and ``buildings_per_call``
    distinct buildings; runs with different ``keys`` (capacity buckets) never share a chunk,
    and runs of one building stay together where possible."""
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


TRACES = {"scan_runs": 0}  # incremented at trace time; tests count recompilations with it


def scan_runs(
    maps, fields, building, params, lanes, evidence, caps, spec, n_img=0, rp=rivals.DEFAULT_RIVALS
):
    """``vmap`` over runs of ``lax.scan(update)``: Decision leaves ``(R, K, L, ...)``.

    ``maps`` (and ``fields``) are stacked per building ``(B, ...)``, run ``r`` reading
    ``building[r]``; ``evidence`` leaves are ``(R, K, ...)``. Jit it once per capacity bucket
    (``decide_runs`` does); ``TRACES`` counts its traces.
    """
    TRACES["scan_runs"] += 1

    def one(b, ev):
        m = jax.tree.map(lambda a: a[b], maps)
        f = None if fields is None else jax.tree.map(lambda a: a[b], fields)
        state = layer.init(m, params, caps, lanes, spec, f, n_img, rp)
        _, dec = jax.lax.scan(partial(layer.update, batched=True), state, ev)
        return dec

    return jax.vmap(one)(building, evidence)


_COMPILED: dict = {}


def _bucket(n: int, minimum: int, step: int) -> int:
    """``max(n, minimum)`` rounded up to a multiple of ``step`` (a floor need not be one)."""
    return -(-max(int(n), int(minimum)) // step) * step


@dataclass(frozen=True)
class _Call:
    """One compiled call of a batch: its runs ``idx`` (into the batch), the program's
    ``key`` and ``make`` (compiles it), its ``args`` and the real runs ``n`` among its rows."""

    idx: np.ndarray
    key: tuple
    make: object
    args: tuple
    n: int


def _calls(inputs: RunInputs, run_building, floorplans, params, lanes, spec, runs_per_call=16,
           buildings_per_call=8, rival_params=rivals.DEFAULT_RIVALS, min_windows=16,
           min_traj=128, min_runs=1, buildings=None, size_classes=False):  # fmt: skip
    """The calls that decide a batch (``decide_runs``' arguments), chunk by chunk; with
    ``size_classes``, each size class's calls in turn (their ``idx`` into the whole batch)."""
    rb = np.asarray(run_building)
    R = rb.shape[0]
    kw = dict(runs_per_call=runs_per_call, buildings_per_call=buildings_per_call,
              rival_params=rival_params, min_windows=min_windows, min_traj=min_traj,
              min_runs=min_runs)  # fmt: skip
    if buildings is None and size_classes and spec.searches:
        classes: dict = {}
        for b in sorted(set(rb.tolist())):
            classes.setdefault(size_class(floorplans[b], rival_params), []).append(b)
        if len(classes) > 1:
            for members in classes.values():
                idx = np.flatnonzero(np.isin(rb, members))
                sub = RunInputs(jax.tree.map(lambda a, i=idx: np.asarray(a)[i], inputs.evidence),
                                inputs.n_windows[idx], inputs.seg_windows[idx],
                                inputs.seg_keyframes[idx])  # fmt: skip
                local = np.searchsorted(np.asarray(members), rb[idx]).astype(np.int32)
                for c in _calls(sub, local, [floorplans[b] for b in members], params, lanes,
                                spec, **kw):  # fmt: skip
                    yield replace(c, idx=idx[c.idx])
            return
    # one grid bucket for every building: one compilation per capacity bucket
    if buildings is None:
        used = sorted(set(rb.tolist()))
        buildings = stack_buildings([floorplans[b] for b in used], spec, rival_params)
    else:
        used = list(range(len(floorplans)))
    all_maps, all_fields, n_img = buildings.maps, buildings.fields, buildings.n_img
    # One capacity bucket for the whole batch: a compilation costs more than the padding.
    k_b = np.full(R, _bucket(int(inputs.seg_windows.max(initial=1)), min_windows, 16))
    t_b = np.full(R, _bucket(int(inputs.seg_keyframes.max(initial=1)), min_traj, 64))
    J = int(np.asarray(inputs.evidence.mask).shape[2])
    P = int(np.asarray(inputs.evidence.ev_mask).shape[2])
    S = int(np.asarray(inputs.evidence.traj_mask).shape[2])
    p = params.as_arrays()
    runs_per_call = max(1, min(runs_per_call, max(R, min_runs)))
    # one scan length for the batch too: a compilation costs more than padded windows
    n_w = _bucket(int(inputs.n_windows.max(initial=1)), min_windows, 16)
    n_b = min(buildings_per_call, len(used))
    for idx in chunks(rb, runs_per_call, n_b, keys=k_b * 65536 + t_b):
        kb, tb = int(k_b[idx[0]]), int(t_b[idx[0]])
        caps = Caps(windows=kb, cands=J, traj=max(tb, S), step=S, evidence=P)
        local_b = list(dict.fromkeys(rb[idx].tolist()))
        rows = [used.index(b) for b in local_b] + [used.index(local_b[0])] * (n_b - len(local_b))
        mp = jax.tree.map(lambda a, r=rows: a[r], all_maps)
        fields = None if all_fields is None else jax.tree.map(lambda a, r=rows: a[r], all_fields)
        bidx = np.asarray([local_b.index(b) for b in rb[idx]], np.int32)
        n = len(idx)
        ev = jax.tree.map(
            lambda a, i=idx, w=n_w: _fit_windows(_pad_rows(np.asarray(a)[i], runs_per_call), w),
            inputs.evidence,
        )
        ev = layer.WindowEvidence(**{**ev.__dict__, "valid": np.where(
            (np.arange(runs_per_call) < n)[:, None], ev.valid, False)})  # fmt: skip
        bidx = _pad_rows(bidx, runs_per_call)
        key = (caps, spec, n_img, rival_params, mp.label.shape, runs_per_call,
               None if fields is None else fields.hit.shape, n_w)  # fmt: skip
        args = (mp, fields, bidx, p, lanes, ev)
        yield _Call(idx, key, partial(_compile, args, caps, spec, n_img, rival_params), args, n)


def compile_runs(inputs: RunInputs, run_building, floorplans, params: DecisionParams,
                 lanes: Lanes, spec: LaneSpec, **kw) -> None:  # fmt: skip
    """Starts compiling, in a background thread each (``background.Pending``), the programs
    ``decide_runs`` will call for inputs of these shapes (any values), and returns at once: a
    later ``decide_runs`` waits for them instead of compiling (``wait_compiled``). Arguments:
    ``decide_runs``' (``progress`` aside)."""
    for c in _calls(inputs, run_building, floorplans, params, lanes, spec, **kw):
        if c.key not in _COMPILED:
            _COMPILED[c.key] = Pending(c.make, "mfcl-compile")


def decide_runs(inputs: RunInputs, run_building, floorplans, params: DecisionParams,
                lanes: Lanes, spec: LaneSpec, progress=None, **kw):  # fmt: skip
    """Every lane's decision at every window of every run.

    Args:
        inputs: ``run_inputs`` of the batch.
        run_building: ``(R,)`` building index of each run into ``floorplans``.
        params, lanes, spec: ``lanes.lanes(...)``.
        progress: optional callable ``progress(runs_done)``.
        kw: ``runs_per_call``, ``buildings_per_call`` (chunk sizes, 16 and 8);
            ``rival_params``; ``min_windows``, ``min_traj`` (the least window and keyframe
            capacities, ``Caps``, and scan length: batches with the same floors share one
            compilation); ``min_runs`` (the least runs per call: rows past the batch are
            padded and masked); ``buildings`` (``stack_buildings(floorplans, ...)``, built once
            by a caller deciding several batches, so that all share one compilation; default:
            the batch's buildings); ``size_classes`` (without ``buildings``, decide the
            buildings of each ``size_class`` apart, on their own grid and path image, one
            compilation per class, so that a small building's searches of the plan do not pay
            for the largest one's image).

    Returns:
        ``(decisions, timing)``: ``Decision`` with host leaves ``(R, K, L, ...)`` and
        ``{"compile_s", "run_s", "searches"}`` (``compile_s``: the wait for compilations).
    """
    R, K = np.asarray(inputs.evidence.valid).shape
    tm = {"compile_s": 0.0, "run_s": 0.0, "searches": 0}
    out, done = None, 0
    for c in _ahead(_calls(inputs, run_building, floorplans, params, lanes, spec, **kw)):
        t0 = time.perf_counter()
        fn = _COMPILED[c.key]
        _COMPILED[c.key] = fn = fn.result() if isinstance(fn, Pending) else fn
        tm["compile_s"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        dec = jax.block_until_ready(fn(*c.args))
        tm["run_s"] += time.perf_counter() - t0
        dec = jax.tree.map(lambda a, n=c.n: _fit_windows(np.asarray(a)[:n], K), dec)
        if out is None:
            out = jax.tree.map(lambda a: np.zeros((R, *a.shape[1:]), a.dtype), dec)
        for o, d in zip(jax.tree.leaves(out), jax.tree.leaves(dec), strict=True):
            o[c.idx] = d
        done += c.n
        if progress is not None:
            progress(done)
    tm["searches"] = int(np.asarray(out.searched)[..., 0].sum()) if out is not None else 0
    return out, tm


def _ahead(calls):
    """``calls`` in order, each one's program compiling (``Pending``, one compilation at a
    time) before it is yielded, and the next program's as soon as the call before it is: the
    calls are read one program ahead (those of the current program buffered: one size class's
    chunks), so a size class compiles while the one before it runs."""
    calls, buf = iter(calls), deque()

    def fill():  # buffer calls up to the first one of a program not compiled yet
        for c in calls:
            buf.append(c)
            if c.key not in _COMPILED:
                _COMPILED[c.key] = Pending(c.make, "mfcl-compile")
                return

    fill()
    while buf:
        c = buf.popleft()
        if all(b.key == c.key for b in buf):
            fill()
        yield c


def wait_compiled() -> None:
    """Waits for every compilation started by ``compile_runs``."""
    for key, c in list(_COMPILED.items()):
        if isinstance(c, Pending):
            _COMPILED[key] = c.result()


def _compile(args, caps, spec, n_img, rival_params):
    fn = jax.jit(scan_runs, static_argnames=("caps", "spec", "n_img", "rp"))
    return fn.lower(*args, caps=caps, spec=spec, n_img=n_img, rp=rival_params).compile()


def size_class(floorplan, rival_params=rivals.DEFAULT_RIVALS) -> tuple[int, int]:
    """``(side, n_img)``: the building's larger raster side in buckets of 256 cells and its
    search image side (``rivals.image_size``); buildings of one class share a compilation."""
    r = floorplan.rasterize()
    return -(-max(r.shape) // 256) * 256, rivals.image_size([floorplan], rival_params)


def _fit_windows(a: np.ndarray, n: int) -> np.ndarray:
    """Axis 1 (windows) cut or zero-padded to ``n``."""
    if a.shape[1] >= n:
        return a[:, :n]
    pad = [(0, 0)] * a.ndim
    pad[1] = (0, n - a.shape[1])
    return np.pad(a, pad)


def _pad_rows(a: np.ndarray, n: int) -> np.ndarray:
    if a.shape[0] >= n:
        return a
    return np.concatenate([a, np.repeat(a[-1:], n - a.shape[0], axis=0)])
