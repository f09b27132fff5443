"""The one decision driver (batch mode): candidates of many runs -> every policy's decision
at every window, in one compiled call.

Gate maps of every building are padded to one bucket and stacked per run, so runs in different
buildings share the compilation. Host code only gathers, pads and turns the result into a
table; the streaming mode for a robot is ``decision.stream``.
"""

from __future__ import annotations

import time

import jax
import numpy as np
import pandas as pd

from mfcl_jax.decision import policies
from mfcl_jax.decision.evaluate import batch_inputs, evaluate, policy_names, to_frame
from mfcl_jax.decision.gate import GateMaps, gate_maps, pad_maps
from mfcl_jax.decision.state import DecisionParams

__all__ = ["run_maps", "decide"]


def run_maps(floorplans, run_building, min_iou: float | None = None) -> GateMaps:
    """Gate maps of the buildings, padded to one bucket and stacked per run ``(R, ...)``."""
    kw = {} if min_iou is None else {"min_iou": min_iou}
    used = sorted(set(int(b) for b in np.asarray(run_building)))
    maps = {b: gate_maps(floorplans[b], **kw) for b in used}
    shape = tuple(int(max(np.asarray(m.label).shape[i] for m in maps.values())) for i in range(2))
    n_rooms = max(m.n_rooms for m in maps.values())
    n_mot = max(int(np.asarray(m.motions).shape[0]) for m in maps.values())
    n_off = max(int(np.asarray(m.offsets).shape[0]) for m in maps.values())
    padded = {}
    for b, m in maps.items():
        m = pad_maps(m, shape, n_rooms, n_mot)
        off, om = np.asarray(m.offsets), np.asarray(m.offsets_mask)
        if off.shape[0] < n_off:
            extra = n_off - off.shape[0]
            off = np.concatenate([off, np.zeros((extra, 2), off.dtype)])
            om = np.concatenate([om, np.zeros(extra, bool)])
        padded[b] = GateMaps(
            m.origin, m.label, m.adjacency, off, om, m.generators, m.generators_mask,
            m.motions, m.motions_mask, m.res,
        )  # fmt: skip
    rows = [padded[int(b)] for b in np.asarray(run_building)]
    return jax.tree.map(lambda *xs: np.stack(xs), *rows)


def decide(
    batch,
    cands,
    floorplans,
    params: DecisionParams | list[DecisionParams] | None = None,
    ours=tuple(policies.OURS_VARIANTS),
    min_iou: float | None = None,
    run_chunk: int = 8,
) -> tuple[pd.DataFrame, dict]:
    """Every policy's decision at every window of every run of a ``WindowBatch``.

    Args:
        batch: ``windows.WindowBatch``.
        cands: ``Candidates`` of ``batch.submaps`` (host).
        floorplans: ``Floorplan`` per building index.
        params: one ``DecisionParams`` or a list (a threshold-set axis, no recompilation).
        ours: names of our variants to evaluate (baselines are always included).
        min_iou: room-congruence threshold override for the gate maps (an ablation).
        run_chunk: runs per step of the sequential map over runs (bounds memory).

    Returns:
        ``(frame, timing)``: one row per run x window x threshold set x policy (columns of
        ``evaluate.to_frame``, ``run`` indexing the batch's runs) and
        ``{"compile_s", "run_s"}``.
    """
    params = params or DecisionParams()
    stacked = DecisionParams.stack(params if isinstance(params, list) else [params])
    maps = run_maps(floorplans, batch.run_building, min_iou)
    var = policies.variants(ours)
    args, n_bad = batch_inputs(cands, batch.submaps, batch.runs, maps, stacked, var)
    t0 = time.perf_counter()
    compiled = evaluate.lower(*args, run_chunk=run_chunk).compile()
    tc = time.perf_counter() - t0
    t0 = time.perf_counter()
    dec = jax.block_until_ready(compiled(*args))
    tr = time.perf_counter() - t0
    frame = to_frame(dec, policy_names(ours), batch.runs.window_mask, n_bad)
    return frame, {"compile_s": tc, "run_s": tr}
