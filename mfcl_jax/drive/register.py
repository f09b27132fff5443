"""Recordings to registered windows: the one place where windows are cut, packed and registered.

The study (``study.pipeline``), the benchmark (``bench.run``) and ``mfcl localize A B C``
(``drive.batch``) all come through ``register``: each group of recordings is cut into windows
(``windows.cut_many``: one LiDAR odometry per sequence, shared by its window lengths), the
windows of every group are packed into one ``WindowBatch`` (points padded to one capacity) and
registered by the caller's ``FrontEnd``. The front-end's call compiles in the background
(``FrontEnd.prepare``) as soon as its point capacity is known (the one asked for, or the first
group's), beside the cutting of the groups that follow.
"""

from __future__ import annotations

from dataclasses import dataclass

from mfcl_jax import windows as W
from mfcl_jax.frontend.candidates import Candidates

__all__ = ["Registered", "register"]


@dataclass(frozen=True, eq=False)
class Registered:
    """The registered windows of a batch of recordings.

    Attributes:
        batch: the ``WindowBatch`` (one run per item, in the items' order).
        cands: the front-end's ``Candidates`` of every submap of ``batch``.
        windows: the ``Windows`` of every item (``batch.windows``).
    """

    batch: W.WindowBatch
    cands: Candidates

    @property
    def windows(self) -> list:
        return self.batch.windows


def register(groups, fe, capacity: int | None = None, rows: int = 1, keep: bool = False,
             on_cut=None, on_packed=None) -> Registered:  # fmt: skip
    """Cuts, packs and registers recordings.

    Args:
        groups: an iterable of lists of ``(seq, WindowParams, building)`` items (building: an
            index into ``fe.floorplans``); a group is cut as it arrives, so a lazy iterable
            (recordings simulated group by group) overlaps its making with the front-end's
            compilation.
        fe: the ``frontend.driver.FrontEnd``.
        capacity: the point capacity of the packed submaps (default: the bucket of the
            fullest submap, ``windows.pack``'s).
        rows: the least batch of the LiDAR odometry's kernel (``windows.cut_many``).
        keep: keep the buildings' front-end features after registering (``FrontEnd``).
        on_cut: optional callable ``on_cut(items, windows)`` after each group is cut.
        on_packed: optional callable ``on_packed(batch)`` once the ``WindowBatch`` is packed,
            before the front-end runs (the study starts compiling its decision programs for
            the batch's shapes there, beside the front-end).

    Returns:
        ``Registered``: one run per item, in order.
    """
    items = []
    prepared = False
    if capacity is not None:
        capacity = int(capacity)
    for group in groups:
        group = list(group)
        if not group:
            continue
        if capacity is not None and not prepared:  # compiles while the group is cut
            fe.prepare(capacity, group[0][2])
            prepared = True
        cut = W.cut_many(((seq, p) for seq, p, _ in group), rows=rows)
        if not prepared:  # ``pack``'s capacity, unless a later group is fuller
            most = max((len(p) for w in cut for p in w.points), default=0)
            fe.prepare(W.bucket(most), group[0][2])
            prepared = True
        if on_cut is not None:
            on_cut(group, cut)
        items += [(seq, w, b) for (seq, _, b), w in zip(group, cut, strict=True)]
    batch = W.pack(items, capacity=capacity)
    if on_packed is not None:
        on_packed(batch)
    cands = fe.register(batch.submaps, batch.building, keep=keep)
    return Registered(batch, cands)
