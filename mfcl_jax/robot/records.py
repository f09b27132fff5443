"""The decisions file's record of a window: the anchor moved to the plan frame, the robot's
pose, the reason and the alternatives (``record``), and the uniqueness test's entry.

The robot's CURRENT pose at window ``k`` is ``T* X_k``: the anchor ``T* = ^B T_L`` (the
plan frame from the odometry frame) composed with the odometry pose ``X_k = ^L T_{S_k}`` of
the window's last scan. A person wants that pose, not the anchor, which is a frame change.
Host float64 throughout, so that large plan coordinates keep their millimetres.
"""

from __future__ import annotations

import math

import numpy as np

from mfcl_jax.decision import lattice
from mfcl_jax.decision.outcome import REASONS, STATE_NAMES
from mfcl_jax.se2 import compose_host, wrap_host

__all__ = ["robot_pose", "record", "record_of", "unique_entry", "storey_view"]


def robot_pose(anchor, X) -> tuple[float, float, float]:
    """``T* X_k``: the pose ``(x, y, yaw)`` (float64, yaw wrapped to ``(-pi, pi]``) from the
    anchor ``(x, y, yaw)`` and the odometry pose ``X`` (radians)."""
    ax, ay, ayaw = (float(v) for v in anchor)
    x, y, yaw = (float(v) for v in X)
    c, s = math.cos(ayaw), math.sin(ayaw)
    t = ayaw + yaw
    return ax + c * x - s * y, ay + s * x + c * y, float(wrap_host(t))


def record(
    decision: dict, X, reason: str, offset=(0.0, 0.0), X_input=None, best=None, rival=None
) -> dict:
    """A decisions-file line: ``decision`` (``Decision.to_json``'s keys, anchor in the local
    frame of the layer's odometry) with its anchor moved to the plan frame (``offset``: plan =
    local + offset, ``Floorplan.offset``), ``pose`` (``T* X_k`` in the plan frame when COMMIT),
    ``reason`` and ``alternatives``. ``X`` is the window's pose in the layer's odometry;
    ``X_input`` the input odometry's pose at the same time (default ``X``): the anchor written
    is the one that places the robot at ``pose`` from the input odometry, ``(T* X) X_input^-1``.

    ``alternatives`` (AMBIGUOUS only, else null): the robot's pose ``A X_k`` in the plan frame
    under each explanation the layer could not tell apart: ``best`` (``T*``), then ``rival``
    (the strongest competitor, or None), both anchors ``(x, y, yaw)`` in the local frame.
    """
    ox, oy = (float(v) for v in offset)
    alt = None
    if decision["state"] == "AMBIGUOUS" and best is not None:
        alt = []
        for a in [best] + ([] if rival is None else [rival]):
            px, py, pyaw = robot_pose(a, X)
            alt.append({"x": px + ox, "y": py + oy, "yaw_deg": math.degrees(pyaw)})
    d = dict(decision, pose=None, reason=str(reason), alternatives=alt)
    a = d["anchor"]
    if a is None:
        return d
    yaw = math.radians(a["yaw_deg"])
    px, py, pyaw = robot_pose((a["x"], a["y"], yaw), X)
    if X_input is not None:
        # (T* X_k) X_input^-1: the pose written, reached from the input odometry.
        xi, yi, yawi = (float(v) for v in X_input)
        ayaw = pyaw - yawi
        c, s = math.cos(ayaw), math.sin(ayaw)
        a = dict(a, x=px - (c * xi - s * yi), y=py - (s * xi + c * yi),
                 yaw_deg=math.degrees(float(wrap_host(ayaw))))  # fmt: skip
    # Large plan coordinates: add the offset last, in float64, so millimetres survive.
    d["anchor"] = dict(a, x=float(a["x"]) + ox, y=float(a["y"]) + oy)
    d["pose"] = {"x": float(px) + ox, "y": float(py) + oy, "yaw_deg": math.degrees(pyaw)}
    return d


def _storey_alternatives(alt, storeys, group, others, offset) -> list:
    """Each alternative named by its storey; the best placement repeated on every storey of
    a shared place (the same spot, moved by the motion between the congruent storeys)."""
    names = storeys.names
    out = []
    first = alt[0]
    if group:
        local = (first["x"] - offset[0], first["y"] - offset[1], math.radians(first["yaw_deg"]))
        stacked = compose_host(storeys.place[group[0]], local)
        for s in group:
            x, y, yaw = storeys.to_storey(s, stacked)
            out.append({"x": x + offset[0], "y": y + offset[1], "yaw_deg": math.degrees(yaw),
                        "storey": names[s]})  # fmt: skip
    else:
        out.append(dict(first, storey=None))
    for a in alt[1:]:
        out.append(dict(a, storey=names[others[0]] if others else None))
    return out


def unique_entry(llr: float, needed: float) -> dict:
    """The decisions file's ``unique`` entry: the uniqueness test's ratio at a window
    (``llr``: NaN where it did not run, written null; +inf where no other placement was
    found, written "inf") and the ratio a commit needs (``needed``, ``log(1 / alpha)``)."""
    if math.isnan(llr):
        value = None
    elif math.isinf(llr):
        value = "inf" if llr > 0 else "-inf"
    else:
        value = round(float(llr), 4)
    return {"llr": value, "needed": round(float(needed), 4)}


OTHER_STOREY = "other storey"  # the reason of a commit on another storey than the one given


def storey_view(storeys, anchor, X) -> tuple[list[int], tuple | None]:
    """Where an anchor of a stacked plan (``floorplan.storeys``) puts the robot: the storeys
    of that place (one, or several congruent ones; the given storey first where it is one of
    them) and the anchor in the first one's frame (None off every storey)."""
    px, py, _ = robot_pose(anchor, X)
    t = storeys.tile_at(px, py)
    if t < 0:
        return [], None
    group = storeys.group(t)
    if storeys.given in group:
        group = [storeys.given] + [s for s in group if s != storeys.given]
    return group, storeys.to_storey(group[0], anchor)


def _with_storeys(d: dict, storeys, X, a, rival) -> tuple:
    """The record's ``storey`` (COMMIT: the storey's name) and ``storeys`` (the storeys
    still possible: the commit's, or those of the explanations of an AMBIGUOUS window; an
    AMBIGUOUS window whose explanations lie on different storeys, or on a place several
    congruent storeys share, has ``symmetry`` ``"storey"``), and the anchors moved to their
    storeys' frames: ``(d, best, rival, its storeys, the rival's storeys)``. Where the user
    named a storey (``Storeys.given``), a commit on its place names it, and a commit on
    another storey's place is DEFER with the reason ``OTHER_STOREY`` (no pose)."""
    names, given = storeys.names, storeys.given
    group, a_s = storey_view(storeys, a, X)
    if d["state"] == "COMMIT" and not group:  # off every storey (the gate keeps it from it)
        d.update(state="DEFER", anchor=None, symmetry=None, tau=None, reason="commit unsupported")
    elif d["state"] == "COMMIT" and given >= 0 and given not in group:
        d.update(state="DEFER", anchor=None, symmetry=None, tau=None, reason=OTHER_STOREY)
        d["storeys"] = [names[s] for s in group]
    elif d["state"] == "COMMIT" and len(group) > 1 and group[0] != given:
        # a place congruent storeys share names none (``decision.storey`` sees to it first)
        d.update(state="AMBIGUOUS", anchor=None, symmetry="storey", tau=None)
    one = len(group) == 1 or (group and group[0] == given)
    d["storey"] = names[group[0]] if d["state"] == "COMMIT" and one else None
    d.setdefault("storeys", None)
    others: list[int] = []
    r_s = None
    if rival is not None:
        others, r_s = storey_view(storeys, rival, X)
    if d["state"] == "COMMIT":
        d["storeys"] = [names[group[0]]]
    elif d["state"] == "AMBIGUOUS":
        both = list(dict.fromkeys(group + others))
        d["storeys"] = [names[s] for s in both] or None
        if len(group) > 1 or (others and others[0] not in group):
            d["symmetry"], d["tau"] = "storey", None
    return d, (a_s or tuple(a)), (r_s if rival is not None else None), group, others


def record_of(dec, k: int, t: float, X, X_input=None, offset=(0.0, 0.0), segment=None,
              unique_llr: float | None = None, storeys=None) -> dict:  # fmt: skip
    """The decisions-file line of one lane's ``Decision`` (host scalars): the state, the
    anchor (when COMMIT), the robot's pose and the reason (``record``); ``k`` the
    window's index over the whole recording, ``segment`` (when given) its odometry segment;
    ``unique_llr`` (a uniqueness lane's ``log(1 / alpha)``) adds ``unique``: the test's ratio
    at this window against that threshold (null where the test did not run). ``storeys``
    (a stacked plan's ``Storeys``) adds ``storey`` and ``storeys`` (``_with_storeys``); the
    anchor, pose and alternatives are then in the storey's own frame, and every alternative
    names its storey (one per storey of a place several congruent storeys share)."""
    state = STATE_NAMES[int(dec.state)]
    kind = lattice.KIND_NAMES[int(dec.kind)]
    a = np.asarray(dec.anchor, np.float64)
    anchor = None
    if state == "COMMIT":
        anchor = {"x": float(a[0]), "y": float(a[1]), "yaw_deg": float(np.rad2deg(a[2]))}
    d = {"k": int(k)}
    if segment is not None:
        d["segment"] = int(segment)
    d |= {
        "t": float(t),
        "state": state,
        "anchor": anchor,
        "symmetry": kind,
        "tau": [float(v) for v in np.asarray(dec.tau)] if kind == "translation" else None,
        "B1": int(dec.b1),
        "B2": int(dec.b2),
        "margin": int(dec.margin),
    }
    rival = tuple(np.asarray(dec.competitor, np.float64)) if bool(dec.has_competitor) else None
    best = tuple(a)
    if storeys is not None:
        d, best, rival, group, others = _with_storeys(d, storeys, X, best, rival)
        if d["state"] == "COMMIT":
            d["anchor"] = {"x": best[0], "y": best[1], "yaw_deg": math.degrees(best[2])}
    d = record(d, X, d.pop("reason", REASONS[int(dec.reason)]), offset, X_input, best, rival)
    if storeys is not None and d["alternatives"]:
        d["alternatives"] = _storey_alternatives(d["alternatives"], storeys, group, others, offset)
    if unique_llr is not None:
        d["unique"] = unique_entry(float(dec.llr), unique_llr)
    return d
