"""Monte Carlo localization (AMCL-like global localization), run once per batch, decided after.

The filter starts from particles spread uniformly over the free space of the floor plan and
uniform in yaw, and at every keyframe applies the odometry motion model, the map prior (a move
through a wall is penalised), the likelihood-field scan model (tempered) and, when the
effective sample size drops below ``resample_ess * N`` or the recovery rule injects uniform
particles (augmented MCL), low-variance resampling (``mcl_model``). The whole time loop is one
``lax.scan``; runs are ``lax.map``ped in chunks and seeds are ``vmap``ped; one compilation per
(static parameters, batch shapes).

The filter never decides: per window end it records the weighted mean pose, the cloud's spread
and the anchor ``^B T_L = P X^-1`` (``MCLTrace``). ``commits`` applies any threshold afterwards
in NumPy, so a risk-coverage sweep over the commit threshold runs the filter once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.peers import mcl_model as mm
from mfcl_jax.peers.mcl_batch import MCLBatch
from mfcl_jax.peers.mcl_params import MCLParams

__all__ = ["MCLParams", "MCLTrace", "make_mcl", "run_mcl", "commits", "trace_count"]

_TRACES = 0


def trace_count() -> int:
    """How many times the filter has been traced (compiled) in this process."""
    return _TRACES


@dataclass(frozen=True)
class MCLTrace:
    """The filter's state at every window end; ``R`` runs, ``S`` seeds, ``K`` windows.

    Attributes:
        pose: ``(R, S, K, 3)`` weighted mean sensor pose in B (circular mean yaw).
        anchor: ``(R, S, K, 3)`` ``^B T_L = pose X^-1`` with ``X`` the odometry at the window end.
        std_xy: ``(R, S, K)`` RMS distance of the weighted cloud to its mean (m).
        std_yaw: ``(R, S, K)`` circular standard deviation of the yaw (rad).
        ess: ``(R, S, K)`` effective sample size after the update (before resampling).
        fit: ``(R, S, K)`` weighted mean over the cloud of the scan's per-beam log-likelihood
            (untempered): how well the cloud explains the scan, whatever its spread.
        window_mask: ``(R, K)`` valid windows.
    """

    pose: np.ndarray
    anchor: np.ndarray
    std_xy: np.ndarray
    std_yaw: np.ndarray
    ess: np.ndarray
    fit: np.ndarray
    window_mask: np.ndarray


def _filter(key, run, tp, n, n_beams, recovery, res):
    """One run, one seed: per-step statistics, a dict of ``(T, ...)`` arrays."""
    shape = run["dist"].shape
    table = mm.likelihood_table(
        run["dist"], tp["sigma_hit"], tp["z_hit"], tp["z_rand"], tp["max_range"], tp["max_dist"]
    )
    cdf = mm.free_cdf(run["free"])
    origin = run["origin"]
    k_init, key = jax.random.split(key)
    particles = mm.sample_free(k_init, cdf, shape, origin, res, n)
    logw = jnp.full((n,), -math.log(n), jnp.float32)
    odom = run["odom"]
    prev = jnp.concatenate([odom[:1], odom[:-1]])  # step 0 does not move
    zero = jnp.float32(0.0)

    def step(carry, x):
        particles, logw, slow0, fast0, key = carry
        l_slow, l_fast = slow0, fast0
        pts, pmask, x_prev, x_cur, valid, first = x
        key, k_mot, k_res, k_inj = jax.random.split(key, 4)
        moved = mm.sample_motion(k_mot, particles, x_prev, x_cur, tp["alpha"])
        beams, bmask = mm.select_beams(pts, pmask, n_beams)
        ll = mm.scan_loglik(moved, beams, bmask, table, origin, res)
        # Thrun's motion_model_with_map: a move through a wall or out of the building is
        # (nearly) impossible whatever the scan says; without it a cloud locked on an alias
        # walks through the walls that the true robot passes through a door.
        off = ~mm.on_map(particles, moved, run["passable"], origin, res)
        upd = logw + tp["temper"] * ll - tp["off_map"] * off.astype(jnp.float32)
        # log sum_i w_i p_i: how well the cloud as a whole explains the scan.
        l_avg = jax.scipy.special.logsumexp(upd)
        upd = upd - l_avg
        w = jnp.exp(upd)
        mean, std_xy, std_yaw, ess = mm.cloud_stats(moved, w)
        fit = jnp.sum(w * ll) / jnp.maximum(jnp.sum(bmask.astype(jnp.float32)), 1.0)
        drawn = moved[mm.low_variance_resample(k_res, w)]
        do = ess < tp["resample_ess"] * n
        if recovery:
            # Augmented MCL (Probabilistic Robotics, Table 8.3; AMCL's recovery_alpha_*): a
            # short-term average of the scan likelihood falling below the long-term one means
            # the cloud is lost, and that fraction of the resampled cloud restarts uniformly.
            # The averages run on logs (geometric means): the tempered likelihoods of a
            # 60-beam scan underflow float32 as plain numbers.
            l_slow = jnp.where(first, l_avg, slow0 + tp["alpha_slow"] * (l_avg - slow0))
            l_fast = jnp.where(first, l_avg, fast0 + tp["alpha_fast"] * (l_avg - fast0))
            p_inj = jnp.maximum(0.0, 1.0 - jnp.exp(l_fast - l_slow))
            swap = jax.random.uniform(k_inj, (n,)) < p_inj
            # Fresh poses for an eighth of the cloud, reused in turn beyond that: drawing n
            # every step would cost a third of the step, and the motion noise of the next
            # step separates the copies of a totally lost cloud anyway.
            cap = max(1, n // 8)
            fresh_draw = mm.sample_free(jax.random.fold_in(k_inj, 1), cdf, shape, origin, res, cap)
            slot = (jnp.cumsum(swap.astype(jnp.int32)) - 1) % cap
            drawn = jnp.where(swap[:, None], fresh_draw[slot], drawn)
            # A cloud that is lost as a whole keeps a high ESS (every particle is equally
            # wrong): injection must not wait for the ESS test.
            do = do | jnp.any(swap)
        nxt = jnp.where(do, drawn, moved)
        nxt_logw = jnp.where(do, jnp.full_like(upd, -math.log(n)), upd)
        # Padded steps leave the cloud as it was.
        carry = (
            jnp.where(valid, nxt, particles),
            jnp.where(valid, nxt_logw, logw),
            jnp.where(valid, l_slow, slow0),
            jnp.where(valid, l_fast, fast0),
            key,
        )
        return carry, dict(mean=mean, std_xy=std_xy, std_yaw=std_yaw, ess=ess, fit=fit)

    first = jnp.arange(odom.shape[0]) == 0
    xs = (run["scans"], run["mask"], prev, odom, run["step_mask"], first)
    init = (particles, logw, zero, zero, key)
    _, out = jax.lax.scan(step, init, xs)
    return out


def _mcl(batch: MCLBatch, keys, tp, n, n_beams, recovery, chunk):
    global _TRACES
    _TRACES += 1
    res = batch.res

    def per_run(args):
        run, run_keys = args
        out = jax.vmap(lambda k: _filter(k, run, tp, n, n_beams, recovery, res))(run_keys)
        out = {k: v[:, run["window_end"]] for k, v in out.items()}  # (S, K, ...)
        pose = out.pop("mean")
        return dict(pose=pose, anchor=se2.anchor(pose, run["odom"][run["window_end"]]), **out)

    runs = dict(
        scans=batch.scans,
        mask=batch.mask,
        odom=batch.odom,
        step_mask=batch.step_mask,
        window_end=batch.window_end,
        dist=batch.dist,
        free=batch.free,
        passable=batch.passable,
        origin=batch.origin,
    )
    # A divisor of R: lax.map compiles the body a second time for a remainder batch.
    n_runs = keys.shape[0]
    size = max(d for d in range(1, min(chunk, n_runs) + 1) if n_runs % d == 0)
    return jax.lax.map(per_run, (runs, keys), batch_size=size)


_mcl_jit = jax.jit(_mcl, static_argnames=("n", "n_beams", "recovery", "chunk"))


def make_mcl(params: MCLParams):
    """The jitted filter for ``params``: ``f(batch, seeds) -> MCLTrace``.

    Every ``make_mcl`` shares one compilation cache: parameters other than the static ones
    (see ``MCLParams``) are passed as arrays, so changing them does not recompile.
    """
    static = params.static()
    tp = params.traced()

    def run(batch: MCLBatch, seeds) -> MCLTrace:
        keys = _seed_keys(batch, seeds)
        out = _mcl_jit(batch, keys, tp, **static)
        out = jax.tree.map(np.asarray, jax.block_until_ready(out))
        return MCLTrace(window_mask=np.asarray(batch.window_mask), **out)

    def lower(batch: MCLBatch, seeds):
        """Ahead-of-time lowering for these shapes (``.compile()`` it to time compilation)."""
        return _mcl_jit.lower(batch, _seed_keys(batch, seeds), tp, **static)

    run.lower = lower
    return run


def _seed_keys(batch: MCLBatch, seeds) -> jax.Array:
    """PRNG keys ``(R, S, 2)``: key of (run, seed) = fold_in(PRNGKey(seed), run_id).

    A run's result thus depends on its ``run_id`` and the seed, not on its batch position.
    """
    seeds = np.asarray(seeds, np.int64).reshape(-1)
    if len(seeds) == 0:
        raise ValueError("run_mcl needs at least one seed")
    base = jnp.stack([jax.random.PRNGKey(int(s)) for s in seeds])
    ids = jnp.asarray(batch.run_id, jnp.uint32)
    return jax.vmap(lambda i: jax.vmap(lambda k: jax.random.fold_in(k, i))(base))(ids)


def run_mcl(batch: MCLBatch, params: MCLParams, seeds=(0,)) -> MCLTrace:
    """Runs the filter on every (run, seed) of ``batch`` (see ``make_mcl``)."""
    return make_mcl(params)(batch, seeds)


def commits(trace: MCLTrace, commit_xy=0.5, commit_yaw_deg=10.0, persist: int = 1) -> np.ndarray:
    """Applies a commit rule to a trace, after the fact (NumPy; no filter re-run).

    A window commits when the cloud's ``std_xy <= commit_xy`` and ``std_yaw <= commit_yaw``
    there and at the ``persist - 1`` windows before it.

    Args:
        trace: ``MCLTrace``.
        commit_xy: position spread bound (m); scalar or broadcastable to ``(R, S)``.
        commit_yaw_deg: yaw spread bound (deg).
        persist: consecutive converged windows required (>= 1).

    Returns:
        ``(R, S, K)`` bool, False at padded windows.
    """
    if not (isinstance(persist, int | np.integer) and persist >= 1):
        raise ValueError(f"commits: persist must be an int >= 1, got {persist!r}")
    xy = np.asarray(commit_xy, np.float64)[..., None]
    yaw = np.deg2rad(np.asarray(commit_yaw_deg, np.float64))[..., None]
    ok = (trace.std_xy <= xy) & (trace.std_yaw <= yaw) & trace.window_mask[:, None, :]
    streak = np.zeros(ok.shape[:-1], np.int64)
    out = np.zeros_like(ok)
    for k in range(ok.shape[-1]):
        streak = np.where(ok[..., k], streak + 1, 0)
        out[..., k] = streak >= persist
    return out
