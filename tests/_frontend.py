"""Shared by the front-end's test files: one registration program for the common raster
bucket (``REG``, traced once per worker), the asymmetric two-room plan and its reference
registration (``asym_run``, at first use, once per worker)."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
from _frontend_synth import batch, make_submap
from shapely.geometry import box

from mfcl_jax import se2
from mfcl_jax.floorplan.model import Door, Floorplan, Room
from mfcl_jax.floorplan.raster import pad_to
from mfcl_jax.frontend import FrontendParams, build_features, make_register, registration
from mfcl_jax.frontend.features import floorplan_corners
from mfcl_jax.windows.arrays import SubmapBatch

N, P = 4, 2048
SHAPE = (200, 360)  # common raster bucket: one compilation for every test floor plan
PARAMS = FrontendParams()
REG = make_register(PARAMS)


def asym_plan() -> Floorplan:
    """Two rooms of different size, one L-shaped, joined by a door (no symmetry)."""
    walls = [
        [[0, 0], [16, 0]],
        [[16, 0], [16, 8]],
        [[16, 8], [0, 8]],
        [[0, 8], [0, 0]],
        [[9, 0], [9, 5]],
        [[9, 6.5], [9, 8]],
        [[0, 5.5], [3, 5.5]],
        [[3, 5.5], [3, 8]],
    ]
    rooms = (
        Room("A", box(0.1, 0.1, 8.9, 7.9).difference(box(0, 5.4, 3.1, 8))),
        Room("B", box(9.1, 0.1, 15.9, 7.9)),
    )
    return Floorplan(
        walls=np.asarray(walls, float),
        thickness=0.2,
        rooms=rooms,
        doors=(Door(np.array([[8.7, 5.75], [9.3, 5.75]]), ("A", "B")),),
        name="asym",
    )


def feats_for(fp):
    r = pad_to(fp.rasterize(0.10), SHAPE, n_rooms=8)
    return build_features(fp, PARAMS, rasters=r, corners=floorplan_corners(fp, capacity=64))


def pad_batch(subs):
    """Batch of N slots (missing ones empty), capacity P."""
    b = batch(subs, P)
    n = len(subs)

    def pad(a, fill=0):
        return np.concatenate(
            [np.asarray(a), np.full((N - n, *np.shape(a)[1:]), fill, np.asarray(a).dtype)]
        )

    return SubmapBatch(
        points=pad(b.points),
        origins=pad(b.origins),
        mask=pad(b.mask, False),
        X=pad(b.X),
        run=pad(b.run),
        window=pad(b.window),
        t=pad(b.t),
        n_dropped=pad(b.n_dropped),
    )


def hits(cands, i, Y, xy=0.5, deg=2.0):
    dxy, dth = se2.distance_pair(cands.pose[i], np.asarray(Y, np.float32))
    return np.asarray((dxy < xy) & (dth < math.radians(deg)) & cands.mask[i])


@cache
def asym_run():
    """The asymmetric plan's three submaps registered in one batch: the plan, the submaps,
    the candidates and how many traces the call took (one: each test file's first use of
    ``REG`` is through its ``asym`` fixture, so this is the worker's first call)."""
    fp = asym_plan()
    subs = [
        make_submap(fp, (2.0, 2.0), (6.0, 3.0), 0.4, n_beams=240),
        make_submap(fp, (11.0, 2.0), (14.0, 5.0), -2.0, n_beams=240),
        make_submap(fp, (6.0, 6.5), (2.0, 4.0), 2.5, n_beams=240),
    ]
    before = registration.TRACE_COUNT[0]
    c = REG(pad_batch(subs), feats_for(fp))
    return fp, subs, c, registration.TRACE_COUNT[0] - before
