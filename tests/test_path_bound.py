"""The branch and bound over every placement of the path (``experiments.audit.path_bound``,
``path_certify``): its cell
bound is never below the log-likelihood of a placement inside the cell, it finds the congruent
copy of a room that explains a walk inside it, and it certifies a walk whose rooms differ. The
bound holds for a plan (outside = walls) and for an occupancy map (outside unobserved, 0.5)."""

import dataclasses
import math

import jax
import numpy as np
import pytest

from experiments.audit import path_bound as pb
from experiments.audit import path_certify as pc
from mfcl_jax.decision import rivals
from mfcl_jax.floorplan.raster import UNOBSERVED
from mfcl_jax.frontend import path_llr
from mfcl_jax.sim.synthetic import PITCH, evidence_at, row_of_rooms, walk


def _case(fp, points, n_scans=8, outside=1.0):
    r = dataclasses.replace(fp.rasterize(), outside=np.float32(outside))
    fields = rivals.rival_fields(r)
    traj = walk(points)
    ks = np.linspace(0, len(traj) - 1, n_scans).round().astype(int)
    pts, org, msk = evidence_at(fp, traj[ks])
    length = float(np.sum(np.hypot(*np.diff(traj[:, :2], axis=0).T)))
    # the odometry frame is the plan frame: the true placement is the identity
    pe = path_llr.path_evidence(pts, org, msk, traj[ks], length)
    return fields, pb.bound_fields(fields), pe, traj[-1]


DISTINCT = [[1.5, 1.5], [6.0, 1.5], [6.0, 3.5], [11.0, 2.5]]


@pytest.fixture(scope="module")
def distinct():
    fp = row_of_rooms(widths=(PITCH, 9.0, 5.5))  # rooms of different lengths
    return _case(fp, DISTINCT)


@pytest.mark.parametrize("outside", [1.0, UNOBSERVED])
def test_the_bound_of_a_cell_is_never_below_a_placement_inside_it(distinct, outside):
    fields, bf, pe, _ = (
        distinct if outside == 1.0
        else _case(row_of_rooms(widths=(PITCH, 9.0, 5.5)), DISTINCT, outside=outside)
    )  # fmt: skip
    assert float(fields.outside) == outside and np.any(np.asarray(fields.bad) == outside)
    pts, pw = np.asarray(pe.pts, np.float64), np.asarray(pe.pw, np.float64)
    free, fw = np.asarray(pe.free, np.float64), np.asarray(pe.fw, np.float64)
    c = (pts[pw > 0] * pw[pw > 0, None]).sum(0) / pw[pw > 0].sum()
    rng = np.random.default_rng(0)
    score = jax.jit(jax.vmap(lambda a: path_llr.log_likelihood(a, pe, fields)))
    consts = (bf.capped, bf.to_free, bf.bad, np.float32(bf.outside),
              np.asarray(bf.origin, np.float32), np.float32(bf.res), np.float32(bf.cap),
              np.float32(0.15), np.float32(0.1), np.float32(0.9))  # fmt: skip
    tight = []
    for h, delta in ((0.4, math.radians(2.0)), (0.1, math.radians(0.5)), (0.02, 0.002)):
        # cells about the truth (u = c, theta = 0), about near misses and anywhere
        centre = np.concatenate([
            np.asarray([[c[0], c[1], 0.0]]) + rng.normal(0, [0.3, 0.3, 0.02], (24, 3)),
            np.column_stack([rng.uniform(-2, 24, 24), rng.uniform(-2, 7, 24),
                             rng.uniform(-math.pi, math.pi, 24)]),
        ]).astype(np.float32)  # fmt: skip
        side = h
        pq, pwv, pr = pb.voxels(pts - c, pw, side)
        fq, fwv, fr = pb.voxels(free - c, fw, side)
        ub = np.asarray(pb.cell_bounds(centre, np.float32(h), np.float32(delta), pq, pwv, pr,
                                       fq, fwv, fr, *consts))  # fmt: skip
        # placements inside each cell, corners included, in standard form
        d = rng.uniform(-1, 1, (len(centre), 12, 3)) * [h, h, delta]
        d[:, :4] = [[h, h, delta], [-h, h, -delta], [h, -h, -delta], [-h, -h, delta]]
        std = pc._standard((centre[:, None] + d).reshape(-1, 3), c).astype(np.float32)
        L = np.asarray(score(std)).reshape(len(centre), 12).max(1)
        assert np.all(ub >= L - 1e-3), (h, delta, np.min(ub - L))
        tight.extend(ub - L)
    # and it is not vacuous: small cells about the truth are bounded within a few nats
    assert np.median(tight[-48:-24]) < 3.0, np.median(tight[-48:-24])


def test_the_search_finds_the_congruent_copy_of_the_room_walked_in():
    fp = row_of_rooms(widths=(PITCH,) * 3)  # congruent rooms at PITCH, doors alike
    pts = np.asarray([[2.0, 1.2], [5.0, 1.2], [5.0, 4.0]]) + [PITCH, 0.0]
    fields, bf, pe, x_now = _case(fp, pts, n_scans=6)
    a_star = np.zeros(3)
    L0 = float(path_llr.log_likelihood(np.zeros(3, np.float32), pe, fields))
    r = pc.certify(pe, fields, bf, a_star, x_now, L0 - math.log(100.0))
    assert r.outcome == "competitor", r
    # a whole room away (one of the other two rooms, or the room turned half a turn)
    assert np.hypot(*(r.competitor[:2])) > 3.0 or abs(r.competitor[2]) > 3.0, r.competitor
    assert r.competitor_llr >= L0 - math.log(100.0)


def test_the_search_certifies_a_walk_through_rooms_that_differ(distinct):
    fields, bf, pe, x_now = distinct
    L0 = float(path_llr.log_likelihood(np.zeros(3, np.float32), pe, fields))
    r = pc.certify(pe, fields, bf, np.zeros(3), x_now, L0 - math.log(100.0))
    assert r.outcome == "certified", r
    # a margin the evidence cannot reach is not certified
    r = pc.certify(pe, fields, bf, np.zeros(3), x_now, L0 - 1e4)
    assert r.outcome == "open", r
