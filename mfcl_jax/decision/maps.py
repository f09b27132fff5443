"""What the decision layer reads of a floor plan: ``DecisionMaps``.

One grid (the floor plan's rasters) carries:

* the cell labels of the feasibility gate (room index, ``DOOR``, ``WALL``, ``OUTSIDE``) and
  the room graph (``gate``);
* the translations between congruent rooms and the building's rotational self-motions, which
  generate the aliases of the probe (``probe``, ``symmetry``);
* the front-end's verification fields (signed wall distance and free-space penalty,
  ``frontend.verify``), with which the certification re-scores the windows under competing
  anchors (``certify``).

Built on the host (NumPy); ``pad_maps`` pads to a shape bucket so buildings share a
compilation.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import numpy as np

from mfcl_jax.decision import congruence, symmetry
from mfcl_jax.floorplan.raster import Rasters

__all__ = [
    "Symmetry",
    "DOOR",
    "WALL",
    "OUTSIDE",
    "CERT_SIGMA_FREE",
    "MIN_CONGRUENT_IOU",
    "DecisionMaps",
    "decision_maps",
    "pad_maps",
    "stack_maps",
]

DOOR, WALL, OUTSIDE = -1, -2, -3
# Width (m) of the free-space penalty kernel of the certification's fields: the front-end's
# default (``FrontendParams.sigma_free``), so the same score judges candidates and competitors.
CERT_SIGMA_FREE = 0.05


@dataclass(frozen=True)
class Symmetry:
    """The building's self-motions at one room-congruence threshold (leaves may carry a
    leading set axis ``(Q, ...)``: one entry per threshold, ``DecisionMaps.sym``).

    Attributes:
        offsets: ``(P, 2)`` translations between congruent rooms (both signs), padded.
        offsets_mask: ``(P,)`` bool.
        generators: ``(G, 2)`` fundamental congruent-room offsets (one sign), padded.
        generators_mask: ``(G,)`` bool.
        motions: ``(M, 3)`` rotational self-motions ``g = (x, y, theta)`` of the building
            (rigid motions by a quarter turn mapping rooms onto distinct congruent rooms; see
            ``symmetry``), padded.
        motions_mask: ``(M,)`` bool.
    """

    offsets: jax.Array
    offsets_mask: jax.Array
    generators: jax.Array
    generators_mask: jax.Array
    motions: jax.Array
    motions_mask: jax.Array


jax.tree_util.register_dataclass(
    Symmetry, data_fields=list(Symmetry.__dataclass_fields__), meta_fields=[]
)


@dataclass(frozen=True)
class DecisionMaps:
    """What the decision layer reads of a floor plan (a pytree; ``res`` static).

    Attributes:
        origin: ``(2,)`` grid lower-left corner (m).
        label: ``(H, W)`` int32 cell label: room index, ``DOOR``, ``WALL`` or ``OUTSIDE``.
        adjacency: ``(R + 1, R + 1)`` bool room graph; index ``R`` is the outside, joined to
            rooms with an exterior door.
        sym: ``Symmetry`` with a leading axis ``(Q, ...)``: one set per room-congruence
            threshold asked for (``decision_maps(min_iou=...)``; a lane picks one).
        sdf4, pen4: ``(H + 1, W + 1, 4)`` the verification fields (``frontend.verify``:
            signed wall distance and free-space penalty, ``stack4`` layout).
        shared: ``(R + 1,)`` bool: the room lies on a place that stands for several congruent
            storeys (``floorplan.storeys``), where a commit cannot name the storey
            (``decision.storey``); all False for one storey.
        res: cell size (m).
    """

    origin: jax.Array
    label: jax.Array
    adjacency: jax.Array
    sym: Symmetry
    sdf4: jax.Array
    pen4: jax.Array
    shared: jax.Array
    res: float = 0.10

    @property
    def n_rooms(self) -> int:
        return int(self.adjacency.shape[-1]) - 1

    @property
    def n_sets(self) -> int:
        return int(self.sym.offsets_mask.shape[-2])


jax.tree_util.register_dataclass(
    DecisionMaps,
    data_fields=["origin", "label", "adjacency", "sym", "sdf4", "pen4", "shared"],
    meta_fields=["res"],
)


def _pad(a: np.ndarray, n: int, what: str = "room offsets") -> tuple[np.ndarray, np.ndarray]:
    if a.shape[0] > n:
        raise ValueError(f"decision_maps: {a.shape[0]} {what} exceed the capacity {n}")
    out = np.zeros((n, a.shape[1]), np.float32)
    out[: a.shape[0]] = a
    return out, np.arange(n) < a.shape[0]


# Rooms whose footprints overlap this much after centroid alignment are treated as translated
# copies, so the alias probe guards their offsets. The paper's notion is exact congruence; we
# deliberately include near-copies (the stand-in rooms 207-209 reach IoU 0.91-0.96) because
# overlapping submap windows are correlated and can rendezvous on a one-room alias early
# (results/congruence.md measures a strict 0.98 against this default).
MIN_CONGRUENT_IOU = 0.8


def _symmetry(source, r, min_iou, max_generators, dedupe):
    """Offsets, generators and rotational motions (host arrays) at one threshold."""
    offs, gens = congruence.translations(source, r, min_iou, dedupe, max_generators)
    if isinstance(source, Rasters):
        mots = np.zeros((0, 3))
    else:
        mots, _ = symmetry.rotational_motions(source, min_iou, dedupe)
    return offs, gens, mots


def _bucket(n: int, minimum: int) -> int:
    cap = minimum
    while cap < n:
        cap *= 2
    return cap


def decision_maps(
    source,
    res: float = 0.10,
    min_iou: float | tuple[float, ...] = MIN_CONGRUENT_IOU,
    max_offsets: int | None = None,
    max_generators: int = 2,
    dedupe: float = 0.5,
    max_motions: int | None = None,
) -> DecisionMaps:
    """Builds ``DecisionMaps`` on the host from a ``Floorplan`` or ready ``Rasters``.

    Args:
        source: a ``Floorplan`` (exterior doors are read from its one-room doors) or
            ``Rasters`` (then the outside is joined to no room).
        res: raster resolution (m) when ``source`` is a floor plan.
        min_iou: IoU after centroid alignment above which two rooms are congruent (room
            polygons for a ``Floorplan``, cell sets for bare ``Rasters``); a tuple gives one
            symmetry set per threshold (``DecisionMaps.sym`` axis ``Q``).
        max_offsets: static capacity of the congruent-room offset list (default: sized to
            the building, a power of two >= 32).
        max_generators: static capacity of the fundamental offsets used by the alias probe.
        dedupe: offsets closer than this (m) are merged; also the multiple-test tolerance and
            the merge distance of rotational motions.
        max_motions: static capacity of the rotational self-motions probed as aliases
            (default: sized to the building, a power of two >= 8). Bare ``Rasters`` carry no
            room polygons and get none.

    Returns:
        ``DecisionMaps`` with NumPy leaves (``jax.tree.map(jnp.asarray, m)`` moves them).
    """
    exterior: set[int] = set()
    if isinstance(source, Rasters):
        r = source.to_numpy()
    elif hasattr(source, "rasterize"):
        r = source.rasterize(res=res).to_numpy()
        for d in source.doors:
            if len(d.rooms) == 1:
                exterior.add(source.room_index(d.rooms[0]))
    else:
        raise TypeError(f"decision_maps: expected a Floorplan or Rasters, got {type(source)!r}")
    n = r.n_rooms
    rid = np.asarray(r.room_id)
    label = np.where(
        rid >= 0, rid, np.where(np.asarray(r.wall), WALL, np.where(r.inside, DOOR, OUTSIDE))
    ).astype(np.int32)
    adj = np.zeros((n + 1, n + 1), bool)
    adj[:n, :n] = np.asarray(r.adjacency, bool)
    adj[n, n] = True
    for i in exterior:
        adj[i, n] = adj[n, i] = True
    ious = (min_iou,) if np.ndim(min_iou) == 0 else tuple(min_iou)
    sets = [_symmetry(source, r, m, max_generators, dedupe) for m in ious]
    n_off = max_offsets or _bucket(max(len(o) for o, _, _ in sets), 32)
    n_mot = max_motions or _bucket(max(len(m) for _, _, m in sets), 8)
    cols = []
    for offs, gens, mots in sets:
        o, om = _pad(offs, n_off)
        g, gm = _pad(gens, max_generators)
        mo, mm = _pad(mots, n_mot, "rotational motions")
        cols.append((o, om, g, gm, mo, mm))
    sym = Symmetry(*(np.stack(c) for c in zip(*cols, strict=True)))
    origin = np.asarray(r.origin, np.float32)
    from mfcl_jax.frontend import verify

    fp = None if isinstance(source, Rasters) else source
    sdf, pen = verify.surface_fields(fp, r, CERT_SIGMA_FREE)
    sdf4, pen4 = verify.stack4(sdf, verify.FAR), verify.stack4(pen, float(r.outside))
    return DecisionMaps(origin, label, adj, sym, sdf4, pen4, _shared(fp, n), float(r.res))


def _shared(fp, n: int) -> np.ndarray:
    """``(n + 1,)``: rooms on a tile of several congruent storeys (``DecisionMaps.shared``)."""
    out = np.zeros(n + 1, bool)
    st = getattr(fp, "storeys", None)
    if st is not None:
        for i, room in enumerate(fp.rooms):
            x, y = room.polygon.representative_point().coords[0]
            t = st.tile_at(x, y)
            out[i] = t >= 0 and st.shared(t)
    return out


def pad_maps(
    m: DecisionMaps,
    shape: tuple[int, int],
    n_rooms: int | None = None,
    n_motions: int | None = None,
    n_offsets: int | None = None,
) -> DecisionMaps:
    """Pads host ``DecisionMaps`` to a grid bucket ``(H, W)`` and a room count (outside stays
    last), and its symmetry sets to ``n_motions`` motions and ``n_offsets`` offsets.

    Padding cells are ``OUTSIDE``; padded rooms are isolated. Lets runs of different buildings
    (or tests) share one compiled shape.
    """
    h, w = np.asarray(m.label).shape
    H, W = shape
    n = m.n_rooms
    R = n if n_rooms is None else n_rooms
    if H < h or W < w or R < n:
        raise ValueError(f"pad_maps: target {shape}, {R} rooms smaller than {(h, w)}, {n} rooms")
    label = np.pad(np.asarray(m.label), ((0, H - h), (0, W - w)), constant_values=OUTSIDE)
    adj = np.zeros((R + 1, R + 1), bool)
    a = np.asarray(m.adjacency)
    adj[:n, :n] = a[:n, :n]
    adj[:n, R] = a[:n, n]
    adj[R, :n] = a[n, :n]
    adj[R, R] = True
    adj[np.arange(R), np.arange(R)] = True
    shared = np.zeros(R + 1, bool)
    shared[:n] = np.asarray(m.shared)[:n]
    s = jax.tree.map(np.asarray, m.sym)
    M = s.motions.shape[1] if n_motions is None else n_motions
    P = s.offsets.shape[1] if n_offsets is None else n_offsets
    cols = []
    for q in range(s.offsets.shape[0]):
        if M < int(s.motions_mask[q].sum()) or P < int(s.offsets_mask[q].sum()):
            raise ValueError(f"pad_maps: symmetry set {q} exceeds {M} motions / {P} offsets")
        mo, mm = _pad(s.motions[q][s.motions_mask[q]], M, "rotational motions")
        o, om = _pad(s.offsets[q][s.offsets_mask[q]], P)
        cols.append((o, om, s.generators[q], s.generators_mask[q], mo, mm))
    sym = Symmetry(*(np.stack(c) for c in zip(*cols, strict=True)))
    pad4 = ((0, H - h), (0, W - w), (0, 0))
    from mfcl_jax.frontend.verify import FAR

    sdf4 = np.pad(np.asarray(m.sdf4), pad4, constant_values=FAR)
    # off the grid the penalty is the plan's outside, the fill stack4 put past the last cell
    pen4 = np.asarray(m.pen4)
    pen4 = np.pad(pen4, pad4, constant_values=float(pen4[-1, -1, 3]))
    return DecisionMaps(np.asarray(m.origin), label, adj, sym, sdf4, pen4, shared, m.res)


def stack_maps(maps: list[DecisionMaps]) -> DecisionMaps:
    """Buildings' maps padded to one bucket and stacked on a leading axis ``(B, ...)``."""
    shape = tuple(int(max(np.asarray(m.label).shape[i] for m in maps)) for i in range(2))
    n_rooms = max(m.n_rooms for m in maps)
    n_mot = max(int(np.asarray(m.sym.motions).shape[1]) for m in maps)
    n_off = max(int(np.asarray(m.sym.offsets).shape[1]) for m in maps)
    padded = [pad_maps(m, shape, n_rooms, n_mot, n_off) for m in maps]
    return jax.tree.map(lambda *xs: np.stack(xs), *padded)
