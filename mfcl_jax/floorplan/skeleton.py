"""The skeleton (medial axis) of a free-space mask as a graph of junctions and branches.

The skeleton is the mask thinned to one-cell-wide lines (Guo-Hall's two-subiteration thinning,
which keeps the mask's topology: one loop per hole, one piece per component). Skeleton cells
with three or more skeleton neighbours are junction cells; 8-connected clusters of them are
the graph's nodes. Every other skeleton cell has at most two neighbours, so what remains after
removing the junction cells is a set of simple paths (and closed loops): the branches, each an
ordered cell list whose ends attach to a node or are free tips.

Spurs (a tip branch shorter than ``spur_factor`` times its node's clearance plus
``spur_extra``) come from corners and wall noise, not from passages: they are deleted and nodes
left with two branches are dissolved into one longer branch, until nothing changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

__all__ = ["Branch", "Node", "SkeletonGraph", "thin", "skeleton_graph"]

# Neighbour order P2..P9 of Guo & Hall: N, NE, E, SE, S, SW, W, NW as (drow, dcol).
_RING = ((-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1), (-1, -1))


def _guo_hall_tables() -> tuple[np.ndarray, np.ndarray]:
    """Deletability of a cell by its 8-neighbour code, for the two subiterations."""
    tables = (np.zeros(256, bool), np.zeros(256, bool))
    for code in range(256):
        p2, p3, p4, p5, p6, p7, p8, p9 = ((code >> k) & 1 for k in range(8))
        c = (
            (not p2 and (p3 or p4))
            + (not p4 and (p5 or p6))
            + (not p6 and (p7 or p8))
            + (not p8 and (p9 or p2))
        )
        n1 = (p9 | p2) + (p3 | p4) + (p5 | p6) + (p7 | p8)
        n2 = (p2 | p3) + (p4 | p5) + (p6 | p7) + (p8 | p9)
        ok = c == 1 and 2 <= min(n1, n2) <= 3
        tables[0][code] = ok and not ((p2 | p3 | (1 - p5)) & p4)
        tables[1][code] = ok and not ((p6 | p7 | (1 - p9)) & p8)
    return tables


_TABLES = _guo_hall_tables()


def thin(mask: np.ndarray) -> np.ndarray:
    """One-cell-wide skeleton ``(H, W)`` bool of a bool mask (Guo-Hall thinning)."""
    h, w = mask.shape
    pad = np.pad(np.asarray(mask, bool), 1)
    flat = pad.ravel()  # a view: writes go to ``pad``
    offs = np.array([dr * (w + 2) + dc for dr, dc in _RING])
    # Only cells on the mask's border can be deleted; track them instead of the whole grid.
    inner = ndimage.binary_erosion(pad, structure=np.ones((3, 3)), border_value=0)
    todo = np.flatnonzero(pad & ~inner)
    idle = 0
    while idle < 2:  # stop after two subiterations in a row deleted nothing
        for table in _TABLES:
            code = np.zeros(todo.size, np.int32)
            for k, o in enumerate(offs):
                code |= flat[todo + o].astype(np.int32) << k
            gone = todo[table[code]]
            if not gone.size:
                idle += 1
                continue
            idle = 0
            flat[gone] = False
            nbrs = (gone[:, None] + offs[None]).ravel()
            todo = np.unique(np.concatenate([todo, nbrs]))
            todo = todo[flat[todo]]
    return pad[1:-1, 1:-1].copy()


@dataclass
class Node:
    """A junction: its cells ``(k, 2)`` (row, col), the clearance-maximal cell, its clearance."""

    cells: np.ndarray
    centre: tuple[int, int]
    clearance: float


@dataclass(eq=False)
class Branch:
    """A skeleton path: cells ``(n, 2)`` (row, col) in order; ``ends`` are node ids or -1."""

    cells: np.ndarray
    ends: tuple[int, int]

    def length(self, res: float) -> float:
        return float(np.hypot(*np.diff(self.cells, axis=0).T).sum() * res)


@dataclass
class SkeletonGraph:
    """Junction nodes by id (>= 1) and the branches between them."""

    nodes: dict[int, Node]
    branches: list[Branch]


def _order(cells: set[tuple[int, int]]) -> list[tuple[int, int]]:
    """Cells of a simple path or loop (each with <= 2 neighbours in the set), in path order."""

    def nbrs(p):
        return [(p[0] + dr, p[1] + dc) for dr, dc in _RING if (p[0] + dr, p[1] + dc) in cells]

    start = next((p for p in cells if len(nbrs(p)) <= 1), next(iter(cells)))
    out, seen = [start], {start}
    while True:
        nxt = [q for q in nbrs(out[-1]) if q not in seen]
        if not nxt:
            return out
        out.append(nxt[0])
        seen.add(nxt[0])


def skeleton_graph(
    skel: np.ndarray, dist: np.ndarray, res: float, spur_factor: float, spur_extra: float
) -> SkeletonGraph:
    """The pruned graph of a thinned skeleton.

    Args:
        skel: ``(H, W)`` bool skeleton from ``thin``.
        dist: ``(H, W)`` clearance (m) of every cell.
        res: cell size (m).
        spur_factor, spur_extra: a tip branch shorter than ``spur_factor * clearance + spur_extra``
            (m, clearance of the node it hangs from) is a spur and is deleted.

    Returns:
        The ``SkeletonGraph``; nodes keep their ids, deleted or dissolved ones are absent.
    """
    n_nb = ndimage.convolve(skel.astype(np.int32), np.ones((3, 3), np.int32), mode="constant")
    junction = skel & (n_nb - 1 >= 3)
    jlab, _ = ndimage.label(junction, structure=np.ones((3, 3)))
    nodes = {}
    for i, sl in enumerate(ndimage.find_objects(jlab), start=1):
        rr, cc = np.nonzero(jlab[sl] == i)
        cells = np.stack([rr + sl[0].start, cc + sl[1].start], 1)
        k = int(np.argmax(dist[cells[:, 0], cells[:, 1]]))
        nodes[i] = Node(cells, (int(cells[k, 0]), int(cells[k, 1])), float(dist[tuple(cells[k])]))
    blab, _ = ndimage.label(skel & ~junction, structure=np.ones((3, 3)))
    h, w = skel.shape
    branches = []
    for i, sl in enumerate(ndimage.find_objects(blab), start=1):
        rr, cc = np.nonzero(blab[sl] == i)
        rr, cc = (rr + sl[0].start).tolist(), (cc + sl[1].start).tolist()
        cells = _order(set(zip(rr, cc, strict=True)))
        ends = []
        for r, c in (cells[0], cells[-1]):
            win = jlab[max(r - 1, 0) : min(r + 2, h), max(c - 1, 0) : min(c + 2, w)]
            ends.append(int(win.max()) if win.max() > 0 else -1)
        if len(cells) == 1 and ends[0] > 0:
            # A one-cell branch may touch two nodes (a link) or one (a tip).
            r, c = cells[0]
            win = jlab[max(r - 1, 0) : min(r + 2, h), max(c - 1, 0) : min(c + 2, w)]
            ids = np.unique(win[win > 0])
            ends = [int(ids[0]), int(ids[-1]) if len(ids) > 1 else -1]
        branches.append(Branch(np.asarray(cells, np.int64).reshape(-1, 2), tuple(ends)))
    graph = SkeletonGraph(nodes, branches)
    _dissolve(graph)
    _prune(graph, res, spur_factor, spur_extra)
    return graph


def _prune(graph: SkeletonGraph, res: float, spur_factor: float, spur_extra: float) -> None:
    """Deletes spurs (module doc), the shortest per node and round, until none is left."""
    while True:
        spurs = []
        for b in graph.branches:
            tips = (b.ends[0] < 0) + (b.ends[1] < 0)
            if tips != 1:
                continue
            node = graph.nodes[max(b.ends)]
            if b.length(res) < spur_factor * node.clearance + spur_extra:
                spurs.append(b)
        if not spurs:
            return
        # One spur per node and round, so that a node whose branches are all short keeps one.
        best: dict[int, Branch] = {}
        for b in spurs:
            n = max(b.ends)
            if n not in best or b.length(res) < best[n].length(res):
                best[n] = b
        gone = {id(b) for b in best.values()}
        graph.branches = [b for b in graph.branches if id(b) not in gone]
        _dissolve(graph)


def _dissolve(graph: SkeletonGraph) -> None:
    """Merges the two branches of every degree-2 node; a degree-1 node becomes a tip."""
    at: dict[int, list[Branch]] = {n: [] for n in graph.nodes}
    for b in graph.branches:
        for e in b.ends:
            if e > 0:
                at[e].append(b)  # twice for a loop from the node back to itself
    gone: set[int] = set()
    for nid in list(graph.nodes):
        mine = at.pop(nid)
        centre = np.asarray([graph.nodes[nid].centre], np.int64)
        if len(mine) == 1:
            cells, ends = _towards(mine[0], nid)
            mine[0].cells, mine[0].ends = np.concatenate([cells, centre]), (ends[0], -1)
        elif len(mine) == 2 and mine[0] is not mine[1]:
            (c1, e1), (c2, e2) = _towards(mine[0], nid), _towards(mine[1], nid)
            merged = Branch(np.concatenate([c1, centre, c2[::-1]]), (e1[0], e2[0]))
            for old, e in ((mine[0], e1[0]), (mine[1], e2[0])):
                if e > 0:
                    at[e] = [merged if x is old else x for x in at[e]]
            gone.update((id(mine[0]), id(mine[1])))
            graph.branches.append(merged)
        else:
            at[nid] = mine
            continue
        del graph.nodes[nid]
    graph.branches = [b for b in graph.branches if id(b) not in gone]


def _towards(b: Branch, nid: int) -> tuple[np.ndarray, tuple[int, int]]:
    """The branch's cells and ends, oriented so that it ends at node ``nid``."""
    if b.ends[1] == nid:
        return b.cells, b.ends
    return b.cells[::-1], b.ends[::-1]
