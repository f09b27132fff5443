"""One jitted call: gate table, consensus and states for every run, prefix, threshold set and
policy variant.

Layout of the result: a ``Decisions`` whose leaves have leading axes ``(R, K, S, V)``, with
``V = len(ours variants) + len(BASELINES)`` (``policy_names`` gives the order). Per run the
gate table ``(K, J, K)`` is computed once (it does not depend on thresholds). Per (threshold
set, prefix) the decision core (champions, groups, lattice over all groups, alias probe) is
computed once per gate mode (on, off) and shared by every variant with that gate flag and by
every threshold set: the sets may differ only in the knobs ``state.KNOBS`` (the floors and the
baselines' ratios), which only ``state.finish`` and the baselines read; the variants' floors
and probe flag are applied after (``state.finish``). The baselines are
``vmap``ped over threshold sets. Runs go through ``lax.map`` in chunks of ``run_chunk`` so
memory stays bounded on a CPU.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from mfcl_jax.decision import gate as gate_mod
from mfcl_jax.decision import lattice, machine, policies
from mfcl_jax.decision.anchors import candidate_anchors, per_run
from mfcl_jax.decision.rivals import RIVAL_SLOTS
from mfcl_jax.decision.state import (
    REASONS,
    STATE_NAMES,
    DecisionParams,
    Decisions,
    certify_core,
    finish,
    prefix_core,
)

__all__ = [
    "RunInputs",
    "NO_RIVAL",
    "evaluate_run",
    "evaluate",
    "batch_inputs",
    "policy_names",
    "to_frame",
    "TRACES",
]

TRACES = {"evaluate": 0}  # incremented at trace time; tests count recompilations with it


def policy_names(ours=tuple(policies.OURS_VARIANTS)) -> tuple[str, ...]:
    return tuple(ours) + policies.BASELINES


@dataclass(frozen=True)
class RunInputs:
    """What the decision layer sees of one run (leaves ``(R, ...)`` when batched).

    Attributes:
        H: ``(K, J, 3)`` candidate anchors; score, mask: ``(K, J)``.
        traj: ``(T, 3)`` odometry at the keyframes; traj_mask: ``(T,)``.
        window_start, window_end: ``(K,)`` first and last keyframe of each window;
        window_mask: ``(K,)``.
        X: ``(K, 3)`` odometry pose of each window's last scan.
        ev_points, ev_origins: ``(K, P, 2)`` evidence sample of each window (its frame);
        ev_mask: ``(K, P)``.
        rivals: ``(E, 3)`` placements of the whole path found by the global search
            (``rivals``); rivals_k: ``(E,)`` int32 0-based prefix each was found at (a
            competitor of the certification from there on; ``NO_RIVAL`` for an empty slot).
    """

    H: jax.Array
    score: jax.Array
    mask: jax.Array
    traj: jax.Array
    traj_mask: jax.Array
    window_start: jax.Array
    window_end: jax.Array
    window_mask: jax.Array
    X: jax.Array
    ev_points: jax.Array
    ev_origins: jax.Array
    ev_mask: jax.Array
    rivals: jax.Array | None = None
    rivals_k: jax.Array | None = None


NO_RIVAL = np.iinfo(np.int32).max

jax.tree_util.register_dataclass(
    RunInputs, data_fields=list(RunInputs.__dataclass_fields__), meta_fields=[]
)


# Prefixes certified together: the certification scores every window of a prefix under every
# explanation at 13 fitted poses (``certify.REFINE``); all prefixes at once asked for a 33 GB
# buffer in the benchmark (8 runs per call), four at a time it stayed under 12 GB in all.
CERT_BATCH = 4


def evaluate_run(r: RunInputs, maps, params, var: policies.Variants, n_cap: int = 3) -> Decisions:
    """Every decision of one run.

    Args:
        r: ``RunInputs`` of the run (padded windows masked by ``window_mask``).
        maps: ``DecisionMaps``; params: ``DecisionParams`` with leaves ``(S,)`` (the sets may
            differ only in ``state.KNOBS``); var: ``Variants`` with leaves ``(V0,)``.

    Returns:
        ``Decisions`` with leading axes ``(K, S, V0 + 4)``.
    """
    kk = r.H.shape[0]
    mask = r.mask & r.window_mask[:, None]
    table = gate_mod.prefix_table(maps, r.H, r.traj, r.traj_mask, r.window_end)  # (K, J, Kp)
    modes = jnp.asarray([True, False])  # gate on / off: the only flag the core depends on
    bounds = (r.window_start, r.window_end)
    evidence = (r.ev_points, r.ev_origins, r.ev_mask & r.window_mask[:, None])
    p0 = jax.tree.map(lambda x: x[0], params)  # the core reads no knob (see KNOBS)
    rivals = None if r.rivals is None else (r.rivals, r.rivals_k)

    def cores_at(k):
        def core(ug):
            cons = table[:, :, k]
            return prefix_core(k, r.H, r.score, mask, cons, r.traj, r.traj_mask, bounds, maps,
                               p0, ug, n_cap)  # fmt: skip

        return jax.vmap(core)(modes)

    cores = jax.vmap(cores_at)(jnp.arange(kk))  # (K, 2 modes, ...)
    on = jax.tree.map(lambda x: x[:, 0], cores)
    certs = jax.lax.map(
        lambda kc: certify_core(
            kc[0], kc[1], r.H, r.score, r.X, evidence, bounds, maps, p0, rivals
        ),
        (jnp.arange(kk), on),
        batch_size=CERT_BATCH,
    )  # (K, ...): only the gated variants certify

    def ours_prefix(p, c2, cert):
        def one(ug, up, uc, bm, dm):
            bm = jnp.where(bm < 0, p.b_min, bm)
            dm = jnp.where(dm < 0, p.delta_min, dm)
            c = jax.tree.map(lambda x: jnp.where(ug, x[0], x[1]), c2)
            return finish(c, cert, maps, p, ug, up, uc, bm, dm)

        return jax.vmap(one)(var.use_gate, var.use_probe, var.use_cert, var.b_min, var.delta_min)

    f = jax.vmap(ours_prefix, in_axes=(None, 0, 0))  # prefixes
    f = jax.vmap(f, in_axes=(0, None, None))  # threshold sets
    raw = f(params, cores, certs)  # (S, K, V0, ...)

    def held(p, d, ug):  # the commit machine over the prefixes of one (set, variant)
        return machine.track(d, r.H, r.score, mask, r.X, p, ug)

    h = jax.vmap(held, in_axes=(None, 1, 0), out_axes=1)  # variants
    ours = jax.vmap(h, in_axes=(0, 0, None))(params, raw, var.use_gate)  # sets
    base = jax.vmap(lambda p: policies.baselines(r.H, r.score, mask, table, r.window_mask, p))(
        params
    )
    ours = jax.tree.map(lambda x: jnp.moveaxis(x, 0, 1), ours)  # (K, S, V0, ...)
    base = jax.tree.map(lambda x: jnp.moveaxis(x, 0, 1), base)  # (K, S, 4, ...)
    return jax.tree.map(lambda a, b: jnp.concatenate([a, b], axis=2), ours, base)


@partial(jax.jit, static_argnames=("n_cap", "run_chunk"))
def evaluate(
    runs: RunInputs, maps, building, params, var, n_cap: int = 3, run_chunk: int = 8
) -> Decisions:
    """``evaluate_run`` over runs (leaves of ``runs`` ``(R, ...)``).

    ``maps`` is one shared ``DecisionMaps`` (``building`` ignored) or a stack ``(B, ...)`` of
    buildings, run ``r`` reading building ``building[r]`` (no per-run copy of the maps).
    """
    TRACES["evaluate"] += 1
    stacked = maps.label.ndim == 3

    def one(xs):
        r, b = xs
        mp = jax.tree.map(lambda a: a[b], maps) if stacked else maps
        return evaluate_run(r, mp, params, var, n_cap)

    b = (
        jnp.asarray(building, jnp.int32)
        if building is not None
        else jnp.zeros(runs.H.shape[0], jnp.int32)
    )
    return jax.lax.map(one, (runs, b), batch_size=run_chunk)


def batch_inputs(
    cands, batch, params, var=None
) -> tuple[RunInputs, DecisionParams, object, np.ndarray]:
    """``RunInputs`` of every run of a ``windows.WindowBatch`` (host arrays).

    Anchoring (``H = Y X^-1``) and the per-run gather happen here, on the way in.

    Returns:
        ``(runs, params, var, n_bad)``: ``n_bad (R, K)`` counts non-finite candidates that
        were rejected.
    """
    sub, rb = batch.submaps, batch.runs
    H = candidate_anchors(cands.pose, sub.X)
    H, s, m, n_bad = per_run(H, cands.score, cands.mask, rb.submap, rb.window_mask)
    idx = np.clip(np.asarray(rb.submap), 0, max(sub.n - 1, 0))
    R = idx.shape[0]
    ev = batch.evidence
    runs = RunInputs(
        H, s, m, rb.traj, rb.traj_mask, rb.window_start, rb.window_end, rb.window_mask,
        np.asarray(sub.X)[idx], np.asarray(ev.points)[idx], np.asarray(ev.origins)[idx],
        np.asarray(ev.mask)[idx] & (np.asarray(rb.submap) >= 0)[..., None],
        np.zeros((R, RIVAL_SLOTS, 3), np.float32), np.full((R, RIVAL_SLOTS), NO_RIVAL, np.int32),
    )  # fmt: skip
    if np.ndim(params.tau_c) == 0:
        params = DecisionParams.stack([params])
    var = policies.variants() if var is None else var
    return runs, params, var, n_bad


def _names(table: dict, codes) -> np.ndarray:
    """``table[code]`` for every code (an object array; vectorised lookup)."""
    lut = np.empty(max(table) + 1, object)
    for k, v in table.items():
        lut[k] = v
    return lut[np.asarray(codes).ravel().astype(np.int64)]


def to_frame(dec: Decisions, names=None, window_mask=None, n_bad=None) -> pd.DataFrame:
    """One row per run x window x threshold set x policy (host side, NumPy/pandas).

    ``x, y, yaw_deg`` hold the policy's anchor (ours: the winner T*, the commit anchor when the
    state is COMMIT); ``tau_x, tau_y`` are NaN unless the kind is translation; ``alt_x, alt_y,
    alt_yaw_deg`` hold the anchor of the strongest competing explanation of an AMBIGUOUS
    decision (``Decisions.competitor``), NaN otherwise. A rotational
    alias is reported by ``kind == "rotation"``; its self-motion stays in
    ``Decisions.alias_motion`` (no column, so the table schema is unchanged).
    """
    d = jax.tree.map(np.asarray, jax.block_until_ready(dec))
    r, k, s, v = d.state.shape
    names = policy_names() if names is None else tuple(names)
    if len(names) != v:
        raise ValueError(f"to_frame: {len(names)} policy names for {v} variants")
    ir, ik, is_, iv = (a.ravel() for a in np.meshgrid(*map(np.arange, (r, k, s, v)), indexing="ij"))
    translation = d.kind.ravel() == lattice.TRANSLATION
    # the competing explanation of an AMBIGUOUS decision (NaN otherwise)
    alt = d.has_competitor.ravel()
    df = pd.DataFrame(
        {
            "run": ir,
            "k": ik + 1,
            "set": is_,
            "policy": np.asarray(names, object)[iv],
            "state": _names(STATE_NAMES, d.state),
            "kind": _names(lattice.KIND_NAMES, d.kind),
            "x": d.anchor[..., 0].ravel(),
            "y": d.anchor[..., 1].ravel(),
            "yaw_deg": np.rad2deg(d.anchor[..., 2].ravel()),
            "tau_x": np.where(translation, d.tau[..., 0].ravel(), np.nan),
            "tau_y": np.where(translation, d.tau[..., 1].ravel(), np.nan),
            "alt_x": np.where(alt, d.competitor[..., 0].ravel(), np.nan),
            "alt_y": np.where(alt, d.competitor[..., 1].ravel(), np.nan),
            "alt_yaw_deg": np.where(alt, np.rad2deg(d.competitor[..., 2].ravel()), np.nan),
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
            "reason": _names(REASONS, d.reason),
            "max_score": d.max_score.ravel(),
        }
    )
    if n_bad is not None:
        cum = np.cumsum(np.asarray(n_bad), axis=1)  # (R, K) rejected non-finite so far
        df["n_rejected_nan"] = cum[ir, ik]
    if window_mask is not None:
        df = df[np.asarray(window_mask)[ir, ik]].reset_index(drop=True)
    return df
