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

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from mfcl_jax.decision import gate as gate_mod
from mfcl_jax.decision import lattice, machine, policies
from mfcl_jax.decision.anchors import candidate_anchors, per_run
from mfcl_jax.decision.state import (
    REASONS,
    STATE_NAMES,
    DecisionParams,
    Decisions,
    finish,
    prefix_core,
)

__all__ = ["evaluate_run", "evaluate", "evaluate_batch", "policy_names", "to_frame", "TRACES"]

TRACES = {"evaluate": 0}  # incremented at trace time; tests count recompilations with it


def policy_names(ours=tuple(policies.OURS_VARIANTS)) -> tuple[str, ...]:
    return tuple(ours) + policies.BASELINES


def evaluate_run(
    H,
    score,
    mask,
    traj,
    traj_mask,
    window_start,
    window_end,
    window_mask,
    maps,
    params,
    var: policies.Variants,
    n_cap: int = 3,
) -> Decisions:
    """Every decision of one run.

    Args:
        H: ``(K, J, 3)`` anchors; score, mask: ``(K, J)`` (padded windows masked).
        traj: ``(T, 3)``; traj_mask: ``(T,)``; window_start, window_end: ``(K,)`` first and
            last trajectory sample of each window; window_mask: ``(K,)``.
        maps: ``GateMaps``; params: ``DecisionParams`` with leaves ``(S,)``;
        var: ``Variants`` with leaves ``(V0,)``.

    Returns:
        ``Decisions`` with leading axes ``(K, S, V0 + 4)``.
    """
    kk = H.shape[0]
    mask = mask & window_mask[:, None]
    table = gate_mod.prefix_table(maps, H, traj, traj_mask, window_end)  # (K, J, Kp)
    modes = jnp.asarray([True, False])  # gate on / off: the only flag the core depends on

    p0 = jax.tree.map(lambda x: x[0], params)  # the core reads no knob (see KNOBS)

    def cores_at(k):
        def core(ug):
            cons = table[:, :, k]
            bounds = (window_start, window_end)
            return prefix_core(k, H, score, mask, cons, traj, traj_mask, bounds, maps, p0, ug,
                               n_cap)  # fmt: skip

        return jax.vmap(core)(modes)

    cores = jax.vmap(cores_at)(jnp.arange(kk))  # (K, 2 modes, ...)

    def ours_prefix(p, c2):
        def one(ug, up, bm, dm):
            bm = jnp.where(bm < 0, p.b_min, bm)
            dm = jnp.where(dm < 0, p.delta_min, dm)
            c = jax.tree.map(lambda x: jnp.where(ug, x[0], x[1]), c2)
            return finish(c, maps, p, ug, up, bm, dm)

        return jax.vmap(one)(var.use_gate, var.use_probe, var.b_min, var.delta_min)

    f = jax.vmap(ours_prefix, in_axes=(None, 0))  # prefixes
    f = jax.vmap(f, in_axes=(0, None))  # threshold sets
    raw = f(params, cores)  # (S, K, V0, ...)

    def held(p, d, ug):  # the commit machine over the prefixes of one (set, variant)
        return machine.track(d, maps, traj, traj_mask, window_end, p, ug)

    h = jax.vmap(held, in_axes=(None, 1, 0), out_axes=1)  # variants
    ours = jax.vmap(h, in_axes=(0, 0, None))(params, raw, var.use_gate)  # sets
    base = jax.vmap(lambda p: policies.baselines(H, score, mask, table, window_mask, p))(params)
    ours = jax.tree.map(lambda x: jnp.moveaxis(x, 0, 1), ours)  # (K, S, V0, ...)
    base = jax.tree.map(lambda x: jnp.moveaxis(x, 0, 1), base)  # (K, S, 4, ...)
    return jax.tree.map(lambda a, b: jnp.concatenate([a, b], axis=2), ours, base)


@partial(jax.jit, static_argnames=("n_cap", "run_chunk"))
def evaluate(
    H,
    score,
    mask,
    traj,
    traj_mask,
    window_start,
    window_end,
    window_mask,
    maps,
    params,
    var,
    n_cap: int = 3,
    run_chunk: int = 8,
) -> Decisions:
    """``evaluate_run`` over runs ``(R, ...)``; ``maps`` shared or stacked ``(R, ...)``."""
    TRACES["evaluate"] += 1
    batched_maps = maps.label.ndim == 3

    def one(xs):
        h, s, m, t, tm, ws, we, wm, mp = xs
        mp = mp if batched_maps else maps
        return evaluate_run(h, s, m, t, tm, ws, we, wm, mp, params, var, n_cap)

    mp = maps if batched_maps else None
    xs = (H, score, mask, traj, traj_mask, window_start, window_end, window_mask, mp)
    return jax.lax.map(one, xs, batch_size=run_chunk)


def batch_inputs(cands, submaps, runs, maps, params, var=None):
    """The positional arguments of ``evaluate`` from the pipeline's batches.

    Anchoring (``H = Y X^-1``) and the per-run gather happen here, on the way in.

    Returns:
        ``(args, n_bad)``: ``evaluate(*args)`` evaluates every decision; ``n_bad (R, K)`` counts
        non-finite candidates that were rejected.
    """
    H = candidate_anchors(cands.pose, submaps.X)
    H, s, m, n_bad = per_run(H, cands.score, cands.mask, runs.submap, runs.window_mask)
    if np.ndim(params.tau_c) == 0:
        params = DecisionParams.stack([params])
    var = policies.variants() if var is None else var
    args = (
        H,
        s,
        m,
        runs.traj,
        runs.traj_mask,
        runs.window_start,
        runs.window_end,
        runs.window_mask,
        maps,
        params,
        var,
    )
    return args, n_bad


def evaluate_batch(
    cands, submaps, runs, maps, params, var=None, n_cap: int = 3, run_chunk: int = 8
):
    """Convenience entry from the pipeline's batches (anchoring and gathering included).

    Args:
        cands: ``Candidates``; submaps: ``SubmapBatch``; runs: ``RunBatch``.
        maps: ``GateMaps``; params: ``DecisionParams`` (scalar or stacked ``(S,)``).
        var: ``Variants`` (default: every entry of ``OURS_VARIANTS``).

    Returns:
        ``(Decisions (R, K, S, V), n_bad (R, K))``.
    """
    args, n_bad = batch_inputs(cands, submaps, runs, maps, params, var)
    return evaluate(*args, n_cap=n_cap, run_chunk=run_chunk), n_bad


def to_frame(dec: Decisions, names=None, window_mask=None, n_bad=None) -> pd.DataFrame:
    """One row per run x window x threshold set x policy (host side, NumPy/pandas).

    ``x, y, yaw_deg`` hold the policy's anchor (ours: the winner T*, the commit anchor when the
    state is COMMIT); ``tau_x, tau_y`` are NaN unless the kind is translation. A rotational
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
    df = pd.DataFrame(
        {
            "run": ir,
            "k": ik + 1,
            "set": is_,
            "policy": np.asarray(names, object)[iv],
            "state": [STATE_NAMES[int(x)] for x in d.state.ravel()],
            "kind": [lattice.KIND_NAMES[int(x)] for x in d.kind.ravel()],
            "x": d.anchor[..., 0].ravel(),
            "y": d.anchor[..., 1].ravel(),
            "yaw_deg": np.rad2deg(d.anchor[..., 2].ravel()),
            "tau_x": np.where(translation, d.tau[..., 0].ravel(), np.nan),
            "tau_y": np.where(translation, d.tau[..., 1].ravel(), np.nan),
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
            "reason": [REASONS[int(x)] for x in d.reason.ravel()],
            "max_score": d.max_score.ravel(),
        }
    )
    if n_bad is not None:
        cum = np.cumsum(np.asarray(n_bad), axis=1)  # (R, K) rejected non-finite so far
        df["n_rejected_nan"] = cum[ir, ik]
    if window_mask is not None:
        df = df[np.asarray(window_mask)[ir, ik]].reset_index(drop=True)
    return df
