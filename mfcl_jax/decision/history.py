"""What the layer keeps of the windows and the path: fixed-size device buffers.

``History`` holds the last ``Caps.windows`` windows (rows oldest first, the newest at row
``n - 1``) with everything later windows still need: the candidates' anchors and scores, each
candidate's running gate walk (``gate.Walk``, so a new keyframe extends it instead of the
whole path being walked again), the keyframe bounds, the odometric distance at the window's
end, its odometry pose and its evidence sample. ``Path`` holds the last ``Caps.traj``
keyframe poses of the odometry (the gate maps new candidates and the probe maps ``T*`` over
them).

Capacities are static, so an update costs the same whatever the history's length. A run that
outlives them is summarised, not truncated silently: the oldest window leaves the history
(``History.dropped`` counts them; the consensus, the certification and the support head-count
then span the newest ``Caps.windows`` windows) and the oldest keyframes leave the path (a
candidate's walk keeps counting them; only walks started later, and the probe, span the
newest ``Caps.traj`` keyframes).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp

from mfcl_jax.decision import gate

__all__ = ["Caps", "History", "Path", "empty_history", "empty_path", "push_path", "push_window"]


@dataclass(frozen=True)
class Caps:
    """Static capacities of the layer's buffers.

    Attributes:
        windows: windows kept (the consensus and the certification span them).
        cands: candidates per window (the front-end's top-J).
        traj: keyframes of the path kept.
        step: new keyframes per update (more arrive through ``layer.advance``).
        evidence: evidence points per window.
        cert_slots: scan-disjoint windows the certification re-scores.
        probe_shifts: period shifts per sign the alias probe gates.
    """

    windows: int = 64
    cands: int = 32
    traj: int = 1024
    step: int = 64
    evidence: int = 128
    cert_slots: int = 12
    probe_shifts: int = 3

    def __post_init__(self):
        for name in self.__dataclass_fields__:
            v = getattr(self, name)
            if not (isinstance(v, int) and v > 0):
                raise ValueError(f"Caps: {name} must be a positive int, got {name}={v!r}")
        if self.step > self.traj:
            raise ValueError(f"Caps: step={self.step} exceeds traj={self.traj}")


@dataclass(frozen=True)
class History:
    """The windows kept, rows oldest first (leaves ``(C, ...)``, scalars ``()``)."""

    n: jax.Array  # () int32 rows filled
    dropped: jax.Array  # () int32 windows that left the buffer
    H: jax.Array  # (C, J, 3) candidate anchors
    score: jax.Array  # (C, J)
    mask: jax.Array  # (C, J) bool (false on empty rows)
    walk: gate.Walk  # (C, J) each candidate's gate walk so far
    support: jax.Array  # (C, J) int32 head-counts (the support baseline)
    start: jax.Array  # (C,) int32 first keyframe (index since the segment began)
    end: jax.Array  # (C,) int32 last keyframe
    s_end: jax.Array  # (C,) odometric distance travelled at the window's end
    X: jax.Array  # (C, 3) odometry pose of the window's last scan
    ev_points: jax.Array  # (C, P, 2) evidence sample, window frame
    ev_origins: jax.Array  # (C, P, 2)
    ev_mask: jax.Array  # (C, P)


@dataclass(frozen=True)
class Path:
    """The keyframes kept (rows oldest first)."""

    pose: jax.Array  # (T, 3)
    n: jax.Array  # () int32 rows filled
    total: jax.Array  # () int32 keyframes seen since the segment began
    dist: jax.Array  # () odometric distance travelled
    last: jax.Array  # (3,) the newest keyframe


for _cls in (History, Path):
    jax.tree_util.register_dataclass(
        _cls, data_fields=list(_cls.__dataclass_fields__), meta_fields=[]
    )


def empty_history(caps: Caps) -> History:
    c, j, p = caps.windows, caps.cands, caps.evidence
    f = jnp.float32
    return History(
        jnp.int32(0), jnp.int32(0), jnp.zeros((c, j, 3), f), jnp.zeros((c, j), f),
        jnp.zeros((c, j), bool), gate.start_walk((c, j)), jnp.zeros((c, j), jnp.int32),
        jnp.zeros(c, jnp.int32), jnp.zeros(c, jnp.int32), jnp.zeros(c, f), jnp.zeros((c, 3), f),
        jnp.zeros((c, p, 2), f), jnp.zeros((c, p, 2), f), jnp.zeros((c, p), bool),
    )  # fmt: skip


def empty_path(caps: Caps) -> Path:
    f = jnp.float32
    return Path(jnp.zeros((caps.traj, 3), f), jnp.int32(0), jnp.int32(0), f(0.0), jnp.zeros(3, f))


def push_path(path: Path, poses, valid) -> Path:
    """Appends the valid rows of ``poses (S, 3)`` (a prefix: ``valid (S,)``); when full, the
    oldest rows leave."""
    if poses.shape[0] == 0:
        return path
    t = path.pose.shape[0]
    m = jnp.sum(valid).astype(jnp.int32)
    shift = jnp.maximum(path.n + m - t, 0)
    pose = jnp.roll(path.pose, -shift, axis=0)
    at = path.n - shift + jnp.arange(poses.shape[0])
    pose = pose.at[jnp.where(valid, at, t)].set(poses.astype(pose.dtype), mode="drop")
    prev = jnp.concatenate([jnp.where(path.total > 0, path.last, poses[0])[None], poses[:-1]])
    step = jnp.linalg.norm(poses[:, :2] - prev[:, :2], axis=-1)
    dist = path.dist + jnp.sum(jnp.where(valid, step, 0.0))
    last = jnp.where(m > 0, poses[jnp.maximum(m - 1, 0)], path.last)
    return Path(pose, path.n + m - shift, path.total + m, dist, last)


def push_window(h: History, row: dict) -> History:
    """Appends one window (``row``: a value per ``History`` field but ``n``/``dropped``, without
    the window axis); when full, the oldest window leaves."""
    c = h.mask.shape[0]
    full = h.n == c
    at = jnp.minimum(h.n, c - 1)

    def put(buf, v):
        buf = jnp.where(full, jnp.roll(buf, -1, axis=0), buf)
        return buf.at[at].set(v.astype(buf.dtype))

    fields = {k: getattr(h, k) for k in History.__dataclass_fields__ if k not in ("n", "dropped")}
    new = {k: jax.tree.map(put, fields[k], row[k]) for k in fields}
    return History(jnp.minimum(h.n + 1, c), h.dropped + full.astype(jnp.int32), **new)
