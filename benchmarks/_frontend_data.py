"""The data and shared settings of ``benchmarks/frontend.py``: the stand-in scenes, the window
lengths, the study's point bucket and driver chunk, the compiler options of every front-end
call, and the submaps (with their true poses) the study's path cuts from the simulator."""

from __future__ import annotations

import jax
import numpy as np

from mfcl_jax import windows as W
from mfcl_jax.frontend import sanitize_submaps
from mfcl_jax.frontend.params import COMPILER_OPTIONS
from mfcl_jax.sources.simulated import simulate
from mfcl_jax.windows.arrays import SubmapBatch

SCENES = ("three_rooms", "symmetric_bays")
D_S = (5.0, 6.0, 7.0)
P_STUDY = 2048  # the study's point bucket (windows.pack of 10 seeds x 3 d_s)
CHUNK = 32  # the study's front-end chunk (study.pipeline.CHUNK)
OPTS = dict(compiler_options=COMPILER_OPTIONS)  # as every front-end call is compiled


def scene_data(seeds) -> dict:
    """``{(scene, d_s): (SubmapBatch, Y (n, 3))}`` over every trajectory of each scene."""
    out = {}
    for name in SCENES:
        recs = simulate(name, seeds=seeds)
        for d_s in D_S:
            items, Y = [], []
            for r in recs:
                w = W.cut(r.seq, W.WindowParams(d_s=d_s))
                items.append((r.seq, w, 0))
                Y.append(np.asarray(r.truth.poses)[w.last_scan()])
            sub = sanitize_submaps(W.pack(items).submaps)
            out[name, d_s] = (sub, np.concatenate(Y).astype(np.float32))
    return out


def rows_of(b: SubmapBatch, idx) -> SubmapBatch:
    return jax.tree.map(lambda a: np.asarray(a)[idx], b)
