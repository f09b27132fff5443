"""Rivals of a commit: where else could the whole path seen so far lie in the building?

The probe synthesises aliases from the building's congruent rooms and rotational
self-motions; the certification also weighs the other consensus groups and each window's
runner-up. None of these is a global view of the path: a half-turn of a long corridor in an
occupancy map, or a wing mirrored about an axis, is none of them. So, at a prefix where the
layer is about to commit, the accumulated path (the windows' evidence samples, placed by
odometry: what the layer already sees) is searched over every rigid placement in the plan
(``frontend.path_search``: exhaustive over headings and translations, then polished), and
the best placements become rivals of ``T*`` in the certification from that prefix on
(``certify``: a rival is ruled out only when some window contradicts it and none favours
it).

Host code: the search is an FFT cross-correlation per heading over the whole plan, far too
heavy for every prefix of every run, so it runs only where a commit is about to happen
(``decision.driver`` in batch, ``decision.stream`` online; the same rule in both).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mfcl_jax.frontend import path_search as ps

__all__ = [
    "RivalParams",
    "DEFAULT_RIVALS",
    "path_cloud",
    "rival_fields",
    "search_rivals",
    "search_into",
    "RIVAL_SLOTS",
]


@dataclass(frozen=True)
class RivalParams:
    """Settings of the rival search (fixed once for every building)."""

    n_rivals: int = 6  # best distinct placements kept per search
    max_searches: int = 3  # searches per run (each at a prefix about to commit)
    ray_fracs: tuple = (0.3, 0.6, 0.85)  # free samples along each evidence ray
    max_points: int = 2048
    max_free: int = 2048
    keep_ratio: float = 0.5  # placements scoring below this share of the best are dropped
    search: ps.SearchParams = ps.SearchParams()


DEFAULT_RIVALS = RivalParams()
RIVAL_SLOTS = DEFAULT_RIVALS.n_rivals * DEFAULT_RIVALS.max_searches  # static rival capacity


def path_cloud(ev_points, ev_origins, ev_mask, X, k: int, p: RivalParams = RivalParams()):
    """The path seen up to window ``k`` (0-based, inclusive) in the odometry frame.

    Args:
        ev_points, ev_origins: ``(K, P, 2)`` evidence sample of each window, in its frame;
        ev_mask: ``(K, P)``; X: ``(K, 3)`` odometry pose of each window's frame.

    Returns:
        ``(points (M, 2), free (Q, 2))``: returns and free-space samples (along the rays and
        at the sensor positions), deduplicated over overlapping windows is not attempted: a
        scan seen by several windows weighs more, as it would in any accumulated map.
    """
    pts, free = [], []
    for w in range(k + 1):
        m = np.asarray(ev_mask[w], bool)
        if not m.any():
            continue
        c, s = np.cos(X[w, 2]), np.sin(X[w, 2])
        R = np.asarray([[c, -s], [s, c]])
        q = np.asarray(ev_points[w], np.float64)[m] @ R.T + X[w, :2]
        o = np.asarray(ev_origins[w], np.float64)[m] @ R.T + X[w, :2]
        pts.append(q)
        fr = np.asarray(p.ray_fracs)[:, None, None]
        free.append((o[None] + fr * (q - o)[None]).reshape(-1, 2))
        free.append(np.unique(np.round(o, 2), axis=0))
    if not pts:
        return np.zeros((0, 2)), np.zeros((0, 2))
    return np.concatenate(pts), np.concatenate(free)


def rival_fields(source, p: RivalParams = RivalParams()) -> ps.PlanFields:
    """The search's ``PlanFields`` of a ``Floorplan`` or ``Rasters``, padded to a bucket of
    256 cells so that buildings share compilations."""
    from mfcl_jax.floorplan.raster import Rasters

    r = source if isinstance(source, Rasters) else source.rasterize()
    shape = tuple(-(-n // 256) * 256 for n in r.shape)
    return ps.plan_fields(r, p.search, shape=shape)


def _fit(a, n, rng):
    out = np.zeros((n, 2), np.float32)
    ok = np.zeros(n, bool)
    if len(a) > n:
        a = a[np.sort(rng.choice(len(a), n, replace=False))]
    out[: len(a)], ok[: len(a)] = a, True
    return out, ok


def search_rivals(points, free, fields: ps.PlanFields, p: RivalParams = RivalParams(),
                  seed: int = 0) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Best rigid placements of a path cloud (odometry frame ``L``) in the plan.

    Returns:
        ``(anchors (n, 3), scores (n,))``, best first: each anchor maps ``L`` into the plan
        frame like ``T*`` does (``n <= n_rivals``; empty for an empty cloud).
    """
    if len(points) == 0:
        return np.zeros((0, 3)), np.zeros(0)
    rng = np.random.default_rng(seed)
    c = points.mean(0)
    cp, cm = _fit(points - c, p.max_points, rng)
    cf, cfm = _fit(free - c, p.max_free, rng)
    ext = float(np.max(np.abs(np.concatenate([cp[cm], cf[cfm]])))) if cm.any() else 1.0
    n_img = int(-(-(2 * ext + 2) / fields.c_res // 128) * 128)  # buckets: few compilations
    g, sc = ps.search(cp, cm, cf, cfm, fields, p.search, n_img)
    g, sc = np.asarray(g, np.float64), np.asarray(sc, np.float64)
    good = np.isfinite(sc)
    if not good.any():
        return np.zeros((0, 3)), np.zeros(0)
    good &= sc >= p.keep_ratio * np.max(sc[good])
    order = np.argsort(-np.where(good, sc, -np.inf))[: min(p.n_rivals, int(good.sum()))]
    return ps.uncentre(g[order], c), sc[order]


def search_into(slots, slots_k, n_done: int, evidence, X, k: int, fields: ps.PlanFields,
                p: RivalParams = RivalParams()) -> int:  # fmt: skip
    """One search where a run is about to commit at prefix ``k``, written into its rival slots.

    The one path shared by the batch driver and the stream, so both search the same cloud and
    fill the same slots.

    Args:
        slots: ``(RIVAL_SLOTS, 3)`` the run's rival anchors, written in place at search
            ``n_done`` (slots ``n_done * n_rivals`` on); slots_k: ``(RIVAL_SLOTS,)`` the prefix
            each was found at, written likewise.
        evidence: ``(ev_points, ev_origins, ev_mask)`` of the run's windows; X: ``(K, 3)``.

    Returns:
        The number of rivals found.
    """
    pts, free = path_cloud(*evidence, np.asarray(X, np.float64), k, p)
    A, _ = search_rivals(pts, free, fields, p)
    slot = n_done * p.n_rivals
    slots[slot : slot + len(A)] = A
    slots_k[slot : slot + len(A)] = k
    return len(A)
