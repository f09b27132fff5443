"""Monte Carlo localization (AMCL-like global localization), run once per batch, decided after.

The filter starts from particles spread uniformly over the free space of the floor plan and
uniform in yaw, and at every keyframe applies the odometry motion model, the map prior (a move
through a wall is penalised), the likelihood-field scan model (tempered) and, when the
effective sample size drops below ``resample_ess * N`` or the recovery rule injects uniform
particles (augmented MCL), low-variance resampling (``mcl_model``). The whole time loop is one
``lax.scan`` per call of ``STEPS`` keyframes, the cloud carried from call to call; runs are
``vmap``ped in chunks of ``MCLParams.chunk``, seeds too; one compilation per (static
parameters, chunk shapes), whatever the recordings' length.

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


def _maps(run, tp):
    """The run's likelihood table and free-cell count (recomputed per call: cheap)."""
    table = mm.likelihood_table(
        run["dist"], tp["sigma_hit"], tp["z_hit"], tp["z_rand"], tp["max_range"], tp["max_dist"]
    )
    return table, mm.free_cdf(run["free"])


def _start(key, run, tp, n, res):
    """One run, one seed: the uniform initial cloud, as the filter's carry."""
    _, cdf = _maps(run, tp)
    k_init, key = jax.random.split(key)
    particles = mm.sample_free(k_init, cdf, run["dist"].shape, run["origin"], res, n)
    logw = jnp.full((n,), -math.log(n), jnp.float32)
    zero = jnp.float32(0.0)
    return (particles, logw, zero, zero, key)


def _filter(carry, run, xs, tp, n, n_beams, recovery, res):
    """One run, one seed, one chunk of steps: ``(carry, dict of (Tc, ...) per-step stats)``."""
    shape = run["dist"].shape
    table, cdf = _maps(run, tp)
    origin = run["origin"]

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

    return jax.lax.scan(step, carry, xs)


_GRIDS = ("dist", "free", "passable", "origin")


def _mcl_start(grids, keys, tp, n, res):
    """Initial carries ``(R, S, ...)`` of the runs ``grids`` (dict of ``_GRIDS``)."""
    return jax.vmap(lambda run, k: jax.vmap(lambda kk: _start(kk, run, tp, n, res))(k))(grids, keys)


def _mcl_steps(grids, xs, carry, tp, n, n_beams, recovery, res):
    """One chunk of steps of every run and seed: ``(carry, per-step stats (R, S, Tc, ...))``."""
    global _TRACES
    _TRACES += 1

    def per_run(run, x, c):
        return jax.vmap(lambda cc: _filter(cc, run, x, tp, n, n_beams, recovery, res))(c)

    return jax.vmap(per_run)(grids, xs, carry)


_start_jit = jax.jit(_mcl_start, static_argnames=("n", "res"))
_steps_jit = jax.jit(_mcl_steps, static_argnames=("n", "n_beams", "recovery", "res"))
STEPS = 128  # keyframes per call: one compilation serves every length


def _runs(n_runs: int, chunk: int) -> int:
    """Runs per call: the largest divisor of ``n_runs`` not above ``chunk``."""
    return max(d for d in range(1, min(chunk, n_runs) + 1) if n_runs % d == 0)


def _inputs(batch: MCLBatch, steps: int) -> tuple:
    """The per-step inputs ``(R, T', ...)``, ``T'`` a multiple of ``steps`` (padding inert)."""
    R, T = batch.step_mask.shape
    T2 = -(-T // steps) * steps
    odom = np.asarray(batch.odom, np.float32)
    prev = np.concatenate([odom[:, :1], odom[:, :-1]], 1)  # step 0 does not move
    first = np.broadcast_to(np.arange(T) == 0, (R, T))
    xs = (batch.scans, batch.mask, prev, odom, batch.step_mask, first)

    def pad(a):  # inert steps: the last pose again, no points, not valid
        a = np.asarray(a)
        widths = [(0, 0), (0, T2 - T)] + [(0, 0)] * (a.ndim - 2)
        return np.pad(a, widths, mode="constant" if a.dtype == bool else "edge")

    return tuple(pad(a) for a in xs)


def make_mcl(params: MCLParams):
    """The filter for ``params``: ``f(batch, seeds) -> MCLTrace``.

    The steps run in calls of ``STEPS`` keyframes (the cloud carried from call to call) and
    ``chunk`` runs (``MCLParams.chunk``), so one compilation serves any recording length (and
    every run count with the same runs per call: the largest divisor not above ``chunk``;
    ``pad_batch`` makes it ``chunk``). Every ``make_mcl`` shares one compilation cache:
    parameters other than the static ones (see ``MCLParams``) are passed as arrays, so
    changing them does not recompile.
    """
    static = params.static()
    n, chunk = static.pop("n"), static.pop("chunk")
    tp = params.traced()

    def run(batch: MCLBatch, seeds) -> MCLTrace:
        keys = _seed_keys(batch, seeds)
        R, T = batch.step_mask.shape
        xs = _inputs(batch, STEPS)
        size = _runs(R, chunk)
        parts = []
        for r0 in range(0, R, size):
            rows = slice(r0, r0 + size)
            # on the device once per chunk of runs, not once per call of steps
            grids = jax.device_put({g: np.asarray(getattr(batch, g))[rows] for g in _GRIDS})
            carry = _start_jit(grids, keys[rows], tp, n=n, res=batch.res)
            stats = []
            for t0 in range(0, xs[0].shape[1], STEPS):
                x = tuple(a[rows, t0 : t0 + STEPS] for a in xs)
                carry, out = _steps_jit(grids, x, carry, tp, n=n, res=batch.res, **static)
                stats.append(jax.tree.map(np.asarray, out))
            parts.append({k: np.concatenate([s[k] for s in stats], 2)[:, :, :T] for k in stats[0]})
        steps = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}  # (R, S, T, ...)
        return _trace(batch, steps)

    def lower(batch: MCLBatch, seeds):
        """Ahead-of-time lowering of one chunk of steps for these shapes (``.compile()`` it to
        time compilation)."""
        keys = _seed_keys(batch, seeds)
        size = _runs(batch.n_runs, chunk)
        xs = tuple(a[:size, :STEPS] for a in _inputs(batch, STEPS))
        grids = {g: np.asarray(getattr(batch, g))[:size] for g in _GRIDS}
        carry = jax.eval_shape(lambda: _start_jit(grids, keys[:size], tp, n=n, res=batch.res))
        return _steps_jit.lower(grids, xs, carry, tp, n=n, res=batch.res, **static)

    run.lower = lower
    return run


@jax.jit
def _anchors(pose, odom):
    return se2.anchor(pose, odom)


def _trace(batch: MCLBatch, steps: dict) -> MCLTrace:
    """The per-step stats read at each run's window ends."""
    we = np.asarray(batch.window_end)  # (R, K)
    rows = np.arange(we.shape[0])[:, None]
    at = {k: np.swapaxes(v, 1, 2)[rows, we] for k, v in steps.items()}  # (R, K, S, ...)
    at = {k: np.swapaxes(v, 1, 2) for k, v in at.items()}  # (R, S, K, ...)
    pose = at.pop("mean")
    odom = np.asarray(batch.odom, np.float32)[rows, we][:, None]  # (R, 1, K, 3)
    anchor = np.asarray(_anchors(pose, np.broadcast_to(odom, pose.shape)))
    return MCLTrace(pose=pose, anchor=anchor, window_mask=np.asarray(batch.window_mask), **at)


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
