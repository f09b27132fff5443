"""Room segmentation of an occupancy map's free space: rooms and corridor segments.

Written from the descriptions of Voronoi-graph segmentations (Thrun 1998; Bormann et al. 2016,
"Room segmentation: survey, implementation, and analysis"); no code was taken from them.

1. Interior: the free cells minus the free space joined to the map border through the walls
   sealed by ``seal`` (the outside). Non-free pockets enclosed by free space and smaller than
   ``clutter_area`` (furniture, sensor specks) count as space for steps 2-4, not as walls.
   Clearance ``D``: distance (m) from a cell to the nearest wall cell's edge.
2. Core: the space a disk of radius ``robot_radius`` sweeps (a morphological opening), which
   drops laser rays, cracks and wall noise. Its skeleton (``skeleton.py``, the medial axis as
   a graph of junction nodes and branches, spurs pruned) carries the tests below.
3. Doorway: a skeleton cell whose clearance is the least within ``window`` along the
   skeleton, at most ``max_door_width / 2``, and at most ``narrowing`` times the largest
   clearance within ``side_reach`` on EACH side (the passage widens again both ways). At such
   a minimum the two nearest wall points lie opposite each other, so the cut runs from the
   nearest wall cell through the doorway cell on to the opposite wall.
4. Junction: a skeleton node (nodes joined by a branch shorter than their clearance count as
   one) with at least three open arms. An arm is open when it goes on ``min_arm`` past the
   cut position (or reaches another node) and has no doorway within ``door_arm`` beyond it
   (an arm through a nearby doorway is a side room: a corridor with office doors is not cut
   at every door). Each open arm is cut perpendicular to the skeleton ``junction_margin``
   past the node's clearance, at the first cell within ``min_arm`` that is corridor-like:
   clearance at most ``corridor_width / 2`` and both rays meet a wall within 1.25 times it
   (an arm opening into a hall, or a branch running diagonally through a room, is not cut).
   The crossing between the cuts becomes a region of its own.
5. Regions: the 4-connected pieces of the core minus the cuts, grown over all the interior
   free cells nearest-to-the-core first, so every interior free cell joins exactly one
   region. Regions under ``min_room_area`` join, smallest first, the neighbour they share the
   most boundary with. Not interior: a small region with no neighbour, and free pieces
   without a core cell (specks and rays no disk of radius ``robot_radius`` fits in).

Long straight corridors are not cut at fixed intervals: equal pieces of one corridor would be
translated copies of each other, which the gate's congruent-room probe reads as a symmetry of
the building, and a featureless corridor is where the decision layer should not commit.
"""

from __future__ import annotations

import heapq

import numpy as np
from scipy import ndimage

from mfcl_jax.floorplan.roomseg_cuts import cut_line, doorways, junction_cuts
from mfcl_jax.floorplan.skeleton import skeleton_graph, thin

__all__ = ["segment_rooms"]

_FOUR = ndimage.generate_binary_structure(2, 1)


def _disk(r: int) -> np.ndarray:
    return np.hypot(*np.mgrid[-r : r + 1, -r : r + 1]) <= r


def segment_rooms(
    free: np.ndarray,
    res: float,
    occ: np.ndarray | None = None,
    seal: float = 0.5,
    robot_radius: float = 0.2,
    max_door_width: float = 1.3,
    narrowing: float = 0.75,
    window: float = 0.5,
    side_reach: float = 2.5,
    junction_margin: float = 0.3,
    min_arm: float = 1.0,
    door_arm: float = 1.0,
    corridor_width: float = 3.0,
    clutter_area: float = 1.0,
    spur_factor: float = 1.5,
    spur_extra: float = 0.3,
    min_room_area: float = 3.0,
) -> np.ndarray:
    """Partitions the interior free cells into rooms and corridor segments (module doc).

    Args:
        free: ``(H, W)`` bool free cells.
        res: cell size (m).
        occ: ``(H, W)`` bool occupied cells; when given, free space connected to the map
            border through the walls sealed by ``seal`` (m) is outside and gets no room.
        robot_radius: radius (m) of the disk that sweeps the core.
        max_door_width, narrowing, window, side_reach: doorway test (module doc; metres).
        junction_margin, min_arm, door_arm, corridor_width: junction test and cuts (module
            doc; metres).
        clutter_area: smaller enclosed non-free pockets (m^2) are clutter, not walls.
        spur_factor, spur_extra: skeleton spur pruning (``skeleton.skeleton_graph``).
        min_room_area: smaller regions (m^2) join a neighbour.

    Returns:
        ``(H, W)`` int32 room labels ``0..R-1``, -1 for cells outside every room.
    """
    if occ is not None and seal > 0:
        free = free & ~_outside(free, occ, res, seal)
    # Clutter (non-free pockets enclosed by free space) is not structure: fill it.
    pockets, n = ndimage.label(ndimage.binary_fill_holes(free) & ~free)
    size = ndimage.sum_labels(np.ones_like(pockets), pockets, np.arange(1, n + 1)) * res * res
    space = free | np.concatenate([[False], size < clutter_area])[pockets]
    edt, near = ndimage.distance_transform_edt(space, return_indices=True)
    dist = np.maximum(edt - 0.5, 0.0) * res
    k = max(1, int(round(robot_radius / res)))
    core = ndimage.binary_dilation(edt > k, structure=_disk(k)) & space
    graph = skeleton_graph(thin(core), dist, res, spur_factor, spur_extra)
    cut = np.zeros_like(free)
    doors = doorways(graph, dist, res, max_door_width, narrowing, window, side_reach)
    for b, i in doors:
        p = graph.branches[b].cells[i]
        u = p - near[:, p[0], p[1]]
        line = cut_line(space, p, u, 2 * dist[tuple(p)] + 0.3, res)
        if line is not None:
            cut[line[:, 0], line[:, 1]] = True
    junction_cuts(
        graph, space, cut, dist, res, doors, junction_margin, min_arm, door_arm, corridor_width
    )
    markers, n = ndimage.label(core & free & ~cut, structure=_FOUR)
    lab = _grow(free, markers)
    lab = _merge_small(lab, n, int(np.ceil(min_room_area / (res * res))))
    ids, inv = np.unique(lab, return_inverse=True)
    out = inv.reshape(lab.shape).astype(np.int32) - (1 if ids[0] == 0 else 0)
    out[lab == 0] = -1
    return out


def _outside(free, occ, res, seal) -> np.ndarray:
    """Free cells reachable from the map border without passing within ``seal`` of a wall."""
    k = max(1, int(round(seal / res)))
    open_space = free & ~ndimage.binary_dilation(occ, structure=_disk(k))
    lab, _ = ndimage.label(open_space)
    border = np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))
    out = np.isin(lab, border[border > 0])
    # Give the sealed band on the outer side of the walls back to the outside.
    return ndimage.binary_dilation(out, iterations=k, mask=free)


def _grow(free, markers) -> np.ndarray:
    """Grows the markers over the free space, nearest-to-the-core cells first."""
    to_core = ndimage.distance_transform_edt(markers == 0)
    cost = np.where(free, np.minimum(to_core, 60000), 65535).astype(np.uint16)
    lab = ndimage.watershed_ift(cost, markers.astype(np.int32), structure=_FOUR)
    comps, _ = ndimage.label(free, structure=_FOUR)
    seeded = np.unique(comps[markers > 0])
    lab[~np.isin(comps, seeded[seeded > 0]) | ~free] = 0
    return lab


def _pairs(lab: np.ndarray) -> dict[tuple[int, int], int]:
    """4-neighbour cell pairs between each pair of labels (> 0)."""
    pairs: dict[tuple[int, int], int] = {}
    for a, b in ((lab[:, :-1], lab[:, 1:]), (lab[:-1, :], lab[1:, :])):
        m = (a > 0) & (b > 0) & (a != b)
        if not m.any():
            continue
        lo, hi = np.minimum(a[m], b[m]), np.maximum(a[m], b[m])
        keys, counts = np.unique(np.stack([lo, hi], 1), axis=0, return_counts=True)
        for (i, j), c in zip(keys.tolist(), counts.tolist(), strict=True):
            pairs[(i, j)] = pairs.get((i, j), 0) + c
    return pairs


def _merge_small(lab: np.ndarray, n: int, min_cells: int) -> np.ndarray:
    """Regions under ``min_cells`` join the neighbour sharing most boundary, smallest first."""
    area = np.bincount(lab.ravel(), minlength=n + 1)
    nbr: dict[int, dict[int, int]] = {i: {} for i in range(1, n + 1)}
    for (i, j), c in _pairs(lab).items():
        nbr[i][j] = nbr[j][i] = c
    into = np.arange(n + 1)
    heap = [(int(area[i]), i) for i in range(1, n + 1) if 0 < area[i] < min_cells]
    heapq.heapify(heap)
    while heap:
        a, i = heapq.heappop(heap)
        if into[i] != i or a != area[i] or a >= min_cells or not nbr[i]:
            continue
        j = max(nbr[i], key=lambda k: (nbr[i][k], k))
        into[i] = j
        area[j] += area[i]
        for k, c in nbr.pop(i).items():
            del nbr[k][i]
            if k != j:
                nbr[j][k] = nbr[k][j] = nbr[j].get(k, 0) + c
        if area[j] < min_cells:
            heapq.heappush(heap, (int(area[j]), j))
    for i in range(1, n + 1):  # resolve chains of merges
        j = i
        while into[j] != j:
            j = into[j]
        into[i] = j
    roots = np.flatnonzero(into == np.arange(n + 1))
    into[np.isin(into, roots[area[roots] < min_cells])] = 0  # small and alone: not interior
    return into[lab]
