"""Decisions as a table: one row per run x window x threshold set x lane (host, pandas);
``decide`` makes the table of a ``WindowBatch`` (``compile_decisions`` starts compiling its programs
ahead).

Made after the jitted work from a ``Decision`` with leaves ``(R, K, L, ...)``: names for the
codes, NaN where a column does not apply.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from mfcl_jax.decision import lattice
from mfcl_jax.decision.inputs import run_inputs
from mfcl_jax.decision.lanes import make_lanes
from mfcl_jax.decision.outcome import REASONS, STATE_NAMES, Decision
from mfcl_jax.decision.runs import compile_runs, decide_runs

__all__ = ["to_frame", "names", "decide", "compile_decisions"]


def names(table: dict, codes) -> np.ndarray:
    """``table[code]`` for every code (an object array; vectorised lookup)."""
    lut = np.empty(max(table) + 1, object)
    for k, v in table.items():
        lut[k] = v
    return lut[np.asarray(codes).ravel().astype(np.int64)]


def to_frame(dec: Decision, spec, window_mask=None) -> pd.DataFrame:
    """One row per run x window x lane.

    ``policy`` and ``set`` name the lane (``LaneSpec.names``, ``LaneSpec.sets``); ``x, y,
    yaw_deg`` hold the lane's anchor (ours: ``T*``, the tracked commit anchor while a commit
    is held); ``tau_x, tau_y`` are NaN unless the kind is translation; ``alt_x, alt_y,
    alt_yaw_deg`` hold the strongest competing explanation of an AMBIGUOUS decision
    (``Decision.competitor``), NaN otherwise. A rotational alias is reported by ``kind ==
    "rotation"``; its self-motion stays in ``Decision.alias_motion``. Where a lane runs the
    uniqueness test or the evidence grid (``spec.unique``, ``spec.grid``), ``test_x, test_y,
    test_yaw_deg`` hold the placement it would commit to where it ran (``llr`` not NaN).
    """
    d = dec
    r, k, n_lanes = d.state.shape
    if len(spec.names) != n_lanes:
        raise ValueError(f"to_frame: {len(spec.names)} lane names for {n_lanes} lanes")
    ir, ik, il = (a.ravel() for a in np.meshgrid(*map(np.arange, (r, k, n_lanes)), indexing="ij"))
    translation = d.kind.ravel() == lattice.TRANSLATION
    alt = d.has_competitor.ravel()
    anchor = d.anchor.reshape(-1, 3)
    comp = d.competitor.reshape(-1, 3)
    tau = d.tau.reshape(-1, 2)
    df = pd.DataFrame(
        {
            "run": ir,
            "k": ik + 1,
            "set": np.asarray(spec.sets)[il],
            "policy": np.asarray(spec.names, object)[il],
            "state": names(STATE_NAMES, d.state),
            "kind": names(lattice.KIND_NAMES, d.kind),
            "x": anchor[:, 0],
            "y": anchor[:, 1],
            "yaw_deg": np.rad2deg(anchor[:, 2]),
            "tau_x": np.where(translation, tau[:, 0], np.nan),
            "tau_y": np.where(translation, tau[:, 1], np.nan),
            "alt_x": np.where(alt, comp[:, 0], np.nan),
            "alt_y": np.where(alt, comp[:, 1], np.nan),
            "alt_yaw_deg": np.where(alt, np.rad2deg(comp[:, 2]), np.nan),
            "B1": d.b1.ravel(),
            "B2": d.b2.ravel(),
            "margin": d.margin.ravel(),
            "n_groups": d.n_groups.ravel(),
            "n_champions": d.n_champions.ravel(),
            "spread": d.spread.ravel(),
            "rooms": d.rooms.ravel(),
            "c_winner": d.c_winner.ravel(),
            "winner_gate": d.winner_gate.ravel(),
            "probe_alias": d.probe_alias.ravel(),
            "probe_c": d.probe_c.ravel(),
            "reason": names(REASONS, d.reason),
            "max_score": d.max_score.ravel(),
            "certified": d.certified.ravel(),
            "searched": d.searched.ravel(),
            "n_rejected_nan": d.n_rejected.ravel(),
            "llr": d.llr.ravel(),
        }
    )
    if spec.unique or spec.grid:
        tested = ~np.isnan(d.llr.ravel())
        test = np.where(tested[:, None], d.test_anchor.reshape(-1, 3), np.nan)
        df["test_x"], df["test_y"] = test[:, 0], test[:, 1]
        df["test_yaw_deg"] = np.rad2deg(test[:, 2])
    if window_mask is not None:
        df = df[np.asarray(window_mask)[ir, ik]].reset_index(drop=True)
    return df


def _lanes_and_inputs(batch, cands, params, ours, baselines, primary, primary_set, kw):
    """``(lanes, spec, the positional arguments of runs.decide_runs, its keywords)``."""
    p, ln, spec = make_lanes(params, ours, baselines, primary, primary_set)
    kw = dict(kw)
    steps = {k: kw.pop(k) for k in ("min_step", "min_head") if k in kw}
    return spec, (run_inputs(batch, cands, **steps), batch.run_building, p, ln, spec), kw


def compile_decisions(batch, cands, floorplans, params=None, ours=("ours",),
                      baselines: bool = True, primary: str | None = "ours",
                      primary_set: int = 0, **kw) -> None:  # fmt: skip
    """Starts compiling, in the background, the programs ``decide`` with the same arguments
    will call (``runs.compile_runs``); ``cands`` need only their shapes. Returns at once."""
    _, (inputs, rb, p, ln, spec), kw = _lanes_and_inputs(
        batch, cands, params, ours, baselines, primary, primary_set, kw
    )
    compile_runs(inputs, rb, floorplans, p, ln, spec, **kw)


def decide(batch, cands, floorplans, params=None, ours=("ours",), baselines: bool = True,
           primary: str | None = "ours", primary_set: int = 0, progress=None, **kw):  # fmt: skip
    """Every lane's decision at every window of a ``WindowBatch``, as a table
    (``runs.decide_runs`` on ``inputs.run_inputs``, then ``to_frame``).

    Args:
        batch: ``windows.WindowBatch`` (with its evidence samples; points not needed).
        cands: ``Candidates`` of ``batch.submaps`` (host).
        floorplans: ``Floorplan`` per building index.
        params: one ``DecisionParams`` or a list of threshold sets (``lanes.make_lanes``).
        ours: our variants (``lanes.OURS_VARIANTS``); baselines: add the baselines.
        primary, primary_set: the lane whose commits trigger the rival search.
        progress: optional callable ``progress(runs_done)``.
        kw: ``min_step``, ``min_head`` (``run_inputs``) and ``decide_runs``' keywords
            (``runs_per_call``, ``buildings_per_call``, ``size_classes``, ``min_windows``,
            ``min_traj``, ...).

    Returns:
        ``(frame, timing)``: ``to_frame``'s rows for the batch's valid windows and
        ``decide_runs``'s timing.
    """
    spec, (inputs, rb, p, ln, _), kw = _lanes_and_inputs(
        batch, cands, params, ours, baselines, primary, primary_set, kw
    )
    dec, tm = decide_runs(inputs, rb, floorplans, p, ln, spec, progress=progress, **kw)
    return to_frame(dec, spec, batch.runs.window_mask), tm
