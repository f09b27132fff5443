"""Synthetic submaps for front-end tests: a tiny NumPy ray caster (no simulator needed)."""

from __future__ import annotations

import numpy as np


def raycast(sensor_xy, heading, segments, n_beams=360, max_range=15.0):
    """Hit points (world) of ``n_beams`` rays from ``sensor_xy`` against ``segments (F, 2, 2)``."""
    ang = heading + np.linspace(-np.pi, np.pi, n_beams, endpoint=False)
    d = np.stack([np.cos(ang), np.sin(ang)], -1)  # (B, 2)
    a, b = segments[:, 0], segments[:, 1]
    e = b - a  # (F, 2)
    w = a - sensor_xy  # (F, 2)
    den = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (B, F)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[None, :, 0] * e[None, :, 1] - w[None, :, 1] * e[None, :, 0]) / den
        u = (w[None, :, 0] * d[:, None, 1] - w[None, :, 1] * d[:, None, 0]) / den
    ok = (np.abs(den) > 1e-12) & (t > 1e-6) & (u >= 0) & (u <= 1) & (t <= max_range)
    t = np.where(ok, t, np.inf)
    r = t.min(1)
    hit = np.isfinite(r)
    return sensor_xy + d[hit] * r[hit, None]


def make_submap(
    fp,
    start,
    end,
    yaw,
    clutter=(),
    n_scans=11,
    n_beams=360,
    noise=0.0,
    rng=None,
    S=None,
    max_range=15.0,
):
    """A submap of scans along ``start -> end``; returns ``(points_S, origins_S, Y)``.

    ``Y = ^B T_S`` is the first scan pose (x, y, yaw) unless ``S`` is given.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    segs = np.asarray(fp.wall_faces)
    if len(clutter):
        segs = np.concatenate([segs, np.asarray(clutter, float).reshape(-1, 2, 2)], 0)
    Y = np.asarray([start[0], start[1], yaw] if S is None else S, float)
    c, s = np.cos(Y[2]), np.sin(Y[2])
    Rt = np.array([[c, s], [-s, c]])  # world -> S rotation
    pts, org = [], []
    for f in np.linspace(0, 1, n_scans):
        o = np.asarray(start, float) * (1 - f) + np.asarray(end, float) * f
        h = raycast(o, yaw, segs, n_beams, max_range)
        h = h + noise * rng.standard_normal(h.shape)
        pts.append((h - Y[:2]) @ Rt.T)
        org.append(np.broadcast_to((o - Y[:2]) @ Rt.T, h.shape))
    return np.concatenate(pts).astype(np.float32), np.concatenate(org).astype(np.float32), Y


def batch(subs, P=None):
    """Pads ``[(pts, org, Y), ...]`` into a ``SubmapBatch`` (host)."""
    from mfcl_jax.windows.arrays import SubmapBatch, bucket

    P = P or bucket(max(len(s[0]) for s in subs))
    n = len(subs)
    pts = np.zeros((n, P, 2), np.float32)
    org = np.zeros((n, P, 2), np.float32)
    mask = np.zeros((n, P), bool)
    for i, (p, o, _) in enumerate(subs):
        k = min(len(p), P)
        pts[i, :k], org[i, :k], mask[i, :k] = p[:k], o[:k], True
    return SubmapBatch(
        points=pts,
        origins=org,
        mask=mask,
        X=np.zeros((n, 3), np.float32),
        run=np.zeros(n, np.int32),
        window=np.arange(n, dtype=np.int32),
        t=np.zeros(n),
        n_dropped=np.zeros(n, np.int32),
    )
