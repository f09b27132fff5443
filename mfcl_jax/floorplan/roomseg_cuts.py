"""Where room segmentation cuts the free space: doorways and corridor junction arms.

Both tests read the skeleton graph of the core and the clearance field; they are steps 3 and 4
of ``mfcl_jax.floorplan.roomseg`` (its module doc has the definitions).
"""

from __future__ import annotations

import numpy as np

from mfcl_jax.floorplan.skeleton import SkeletonGraph

__all__ = ["doorways", "cut_line", "junction_cuts"]


def _profile(graph: SkeletonGraph, b: int, dist, res):
    """Arc length (m) and clearance along branch ``b``, its end nodes' clearances appended."""
    br = graph.branches[b]
    step = np.hypot(*np.diff(br.cells, axis=0).T) * res
    s = np.concatenate([[0.0], np.cumsum(step)])
    d = dist[br.cells[:, 0], br.cells[:, 1]]
    for end, at in ((0, -res), (1, s[-1] + res)):
        if br.ends[end] > 0:
            s = np.append(s, at)
            d = np.append(d, graph.nodes[br.ends[end]].clearance)
    return s[: len(br.cells)], d[: len(br.cells)], s, d


def doorways(graph, dist, res, max_door_width, narrowing, window, side_reach):
    """``[(branch index, cell index)]`` of the doorway cells (``roomseg`` module doc, step 3)."""
    out = []
    for b in range(len(graph.branches)):
        s, d, s_all, d_all = _profile(graph, b, dist, res)
        cand = np.flatnonzero(d <= max_door_width / 2)
        taken: list[float] = []
        for i in cand[np.argsort(d[cand], kind="stable")]:
            near = np.abs(s_all - s[i]) <= window
            if d[i] > d_all[near].min() or any(abs(s[i] - t) <= 2 * window for t in taken):
                continue
            left = (s_all < s[i]) & (s_all >= s[i] - side_reach)
            right = (s_all > s[i]) & (s_all <= s[i] + side_reach)
            if not (left.any() and right.any()):
                continue
            if d[i] <= narrowing * min(d_all[left].max(), d_all[right].max()):
                taken.append(s[i])
                out.append((b, int(i)))
    return out


def cut_line(space, p, u, reach, res) -> np.ndarray | None:
    """Cells ``(k, 2)`` from ``p`` along ``u`` and ``-u`` up to the first non-free cell each
    way, or None if a ray meets none within ``reach`` (m)."""
    u = np.asarray(u, float) / max(float(np.hypot(*u)), 1e-9)
    h, w = space.shape
    t = np.arange(0.0, reach / res, 0.5)  # half-cell steps: an 8-connected line of cells
    rays = []
    for sign in (1.0, -1.0):
        rc = np.rint(p[None] + sign * t[:, None] * u[None]).astype(np.int64)
        ok = (rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)
        inside = np.zeros(len(t), bool)
        inside[ok] = space[rc[ok, 0], rc[ok, 1]]
        stop = np.flatnonzero(~inside)
        if not stop.size:
            return None
        rays.append(rc[: stop[0]])
    return np.concatenate(rays)


def junction_cuts(
    graph, space, cut, dist, res, doors, margin, min_arm, door_arm, corridor_width
) -> None:
    """Cuts the open arms of every skeleton junction (``roomseg`` module doc, step 4)."""
    parent = {n: n for n in graph.nodes}

    def root(n):
        while parent[n] != n:
            n = parent[n]
        return n

    for br in graph.branches:
        a, b = br.ends
        if a > 0 and b > 0 and a != b:
            if br.length(res) < min(graph.nodes[a].clearance, graph.nodes[b].clearance):
                parent[root(a)] = root(b)
    door_at: dict[int, list[int]] = {}
    for b, i in doors:
        door_at.setdefault(b, []).append(i)
    arms: dict[int, list[tuple[int, int]]] = {}
    for bi, br in enumerate(graph.branches):
        ends = [root(e) if e > 0 else -1 for e in br.ends]
        if ends[0] == ends[1] > 0:
            if br.length(res) < min(graph.nodes[e].clearance for e in br.ends):
                continue  # inside one junction group
        for side in (0, 1):
            if ends[side] > 0:
                arms.setdefault(ends[side], []).append((bi, side))
    group_clear: dict[int, float] = {}
    for n, node in graph.nodes.items():
        group_clear[root(n)] = max(group_clear.get(root(n), 0.0), node.clearance)
    for group, group_arms in arms.items():
        clear = group_clear[group]
        s_cut = clear + margin
        plans = []
        for bi, side in group_arms:
            br = graph.branches[bi]
            cells = br.cells if side == 0 else br.cells[::-1]
            s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(cells, axis=0).T) * res)])
            idx = door_at.get(bi, [])
            door_s = [s[i] if side == 0 else s[-1 - i] for i in idx]
            if any(ds <= s_cut + door_arm for ds in door_s):
                continue  # leads through a doorway: a side room, not a corridor arm
            far_end = br.ends[1 - side]
            if s[-1] < s_cut + (0.0 if far_end > 0 else min_arm):
                continue
            plans.append((cells, s))
        if len(plans) < 3:
            continue
        for cells, s in plans:
            # Across a corridor both walls are about the clearance away; an arm opening into
            # a hall, or a skeleton branch running diagonally through a room, has none there.
            # Side doors break that too, so the cut may slide up to ``min_arm`` along the arm.
            first, last = np.searchsorted(s, [s_cut, s_cut + min_arm])
            for i in range(int(first), int(last)):
                lo, hi = max(i - 3, 0), min(i + 3, len(cells) - 1)
                t = cells[hi] - cells[lo]
                p = cells[i]
                if dist[tuple(p)] > corridor_width / 2:
                    continue
                line = cut_line(space, p, (-t[1], t[0]), 1.25 * dist[tuple(p)] + 2 * res, res)
                if line is not None:
                    cut[line[:, 0], line[:, 1]] = True
                    break
