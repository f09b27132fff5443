"""Whether the newest scan agrees with a commit's pose: the window's last scan fitted to the plan.

A commit's pose at a window is its anchor times the odometry pose of the window's last scan.
The anchor comes from registrations of whole windows (6 m of submap), and a submap inherits
every turn the odometry takes inside it: when the LiDAR odometry turns the heading a few
degrees too far within a window, that window's registration (and the per-prefix winner, and
the tracked commit) place the last scan a few degrees off, and nothing the rules read
disagrees. The window's last scan alone (``windows.end_sample`` of ``Windows.last_points``,
in its own frame) is free of that bend: no odometry increment has moved its points.
``verdict`` climbs the plan's wall-proximity field (``PlanFields.hit``) from the reported
pose with those points, in rounds of 27 poses (``STEPS``: 2 deg / 0.2 m down to 0.25 deg /
2.5 cm, up to 8 deg and 0.8 m away), and says the pose has drifted when the climb ends
farther than ``machine.TRACK`` in heading from it. Where those points touch no wall near the
reported pose at all (``MIN_SUPPORT``), the commit is unsupported: the robot is in a stretch
the plan does not show, carried by odometry alone (measured: a held-out log map missing a
stretch, through which a right commit was carried for ten windows while the odometry's
heading slipped 5 deg).

The last scan, not the last metre of scans: odometry that arrives late (the benchmark's
``latency`` axis, 0.15-0.3 s) lags the heading by the turn rate times the delay at a sharp
corner (17-35 deg), more than the LiDAR odometry corrects in one step, for a keyframe or two.
The scans of the last metre are then placed relative to the last one with that error; the
earlier ones, still right, outvote it, and the climb stays where the wrong pose is (the
window of ``plain-0/A`` at the corner: 11.7 and 19.9 deg off, reported COMMIT). The last scan
alone climbs away from it.

Heading only: one scan pins the heading wherever it sees two walls at an angle, or one wall,
but may leave a direction free (a corridor), along which the climb slides on noise.
"""

from __future__ import annotations

import itertools
import math

import jax
import jax.numpy as jnp
import numpy as np

from mfcl_jax import se2
from mfcl_jax.decision.machine import DRIFTED, TRACK, UNSUPPORTED
from mfcl_jax.frontend.path_fields import PlanFields, sample_field
from mfcl_jax.sparse_cond import sparse_cond

__all__ = ["STEPS", "MIN_POINTS", "MIN_SUPPORT", "DRIFTED", "UNSUPPORTED", "verdict", "check"]

# (step in m, step in deg, rounds): a round moves to the best of the 27 poses around
STEPS = ((0.2, 2.0, 4), (0.1, 1.0, 2), (0.05, 0.5, 2), (0.025, 0.25, 1))
MIN_POINTS = 16  # fewer points in the last scan: nothing to tell, no verdict
# Mean wall proximity (``hit``, 0-1) of the last scan at the reported pose under which the
# scan touches no wall near it: a stretch the plan does not show (or a pose far off), where
# the pose rests on odometry alone. Far under every right commit's (measured on the last
# metre of scans, which the check read before it read the last scan alone: on the
# benchmark's real logs their 1st percentile was 0.13-0.20, in the simulated runs 0.42).
MIN_SUPPORT = 0.05
_UNIT = np.asarray(list(itertools.product((-1.0, 0.0, 1.0), repeat=3)), np.float32)  # (27, 3)
_CENTRE = 13  # (0, 0, 0)


def _score(poses, pts, w, fields: PlanFields):
    """Mean wall proximity of ``pts (N, 2)`` (weights ``w (N,)``) under ``poses (M, 3)``."""
    q = se2.apply(poses, pts)  # (M, N, 2)
    h = sample_field(fields.hit, fields.origin, fields.res, q, 0.0)
    return jnp.sum(h * w, axis=-1)


def _climb(pose, pts, w, fields: PlanFields):
    """Where the climb from ``pose (3,)`` with ``pts (N, 2)`` (weights ``w``) ends."""
    for step_xy, step_deg, rounds in STEPS:
        scale = jnp.asarray([step_xy, step_xy, math.radians(step_deg)], jnp.float32)

        def one(_, at, scale=scale):
            poses = at[None] + _UNIT * scale
            s = _score(poses, pts, w, fields)
            j = jnp.argmax(s)
            # the centre keeps ties: no sliding on flat ground
            return jnp.where(s[j] > s[_CENTRE] + 1e-6, poses[j], at)

        pose = jax.lax.fori_loop(0, rounds, one, pose)
    return pose


def verdict(pose, pts, mask, fields: PlanFields):
    """``()`` int32: ``UNSUPPORTED`` where the last scan's mean wall proximity at ``pose``
    is under ``MIN_SUPPORT``, else ``DRIFTED`` where its climb from ``pose`` ends farther than
    ``machine.TRACK`` in heading from it, else 0 (and 0 with fewer than ``MIN_POINTS``
    points)."""
    pose, pts = jnp.asarray(pose, jnp.float32), jnp.asarray(pts, jnp.float32)
    mask = jnp.asarray(mask, bool)
    w = mask.astype(jnp.float32) / jnp.maximum(jnp.sum(mask), 1).astype(jnp.float32)
    support = _score(pose[None], pts, w, fields)[0]
    _, dth = se2.distance_pair(_climb(pose, pts, w, fields), pose)
    code = jnp.where(support < MIN_SUPPORT, UNSUPPORTED, jnp.where(dth > TRACK[1], DRIFTED, 0))
    return jnp.where(jnp.sum(mask) >= MIN_POINTS, code, 0).astype(jnp.int32)


def _verdict(ops):
    fields, pose, pts, mask = ops
    return verdict(pose, pts, mask, fields)


def check(fields: PlanFields, poses, need, pts, mask):
    """``verdict`` of every lane's reported pose ``poses (L, 3)`` where ``need (L,)`` (its
    COMMIT), 0 elsewhere, for one window's last scan ``pts (N, 2)``, ``mask (N,)``. Lanes
    reporting the very same pose share one climb (most lanes commit alike); each climb runs
    through ``sparse_cond``, so a window without a commit pays nothing."""
    same = jnp.all(poses[:, None] == poses[None], axis=-1) & need[:, None] & need[None]
    rep = jnp.argmax(same, axis=1)  # the first lane with this pose (itself if none before)
    first = need & (rep == jnp.arange(need.shape[0]))
    v = jax.vmap(lambda n, pose: sparse_cond(n, _verdict, (fields, pose, pts, mask)))(first, poses)
    return jnp.where(need, v[rep], 0)
