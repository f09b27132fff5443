"""Rotational aliases: a building of two L-shaped units, unit B the 180-degree image of unit A.

Layout (centre lines, metres; unit B is ``(x, y) -> (22 - x, 8 - y)`` of unit A)::

    y=11 +----+
         | S  |                        S: storage, only in unit A (breaks the rotation)
    y=8  +----+----+--+---------+
         | LA |BA  |C |   LB    |      LA/LB: L-shaped living rooms, BA/BB: bedrooms,
    y=4  |    +----+  +----+    |      C: corridor, joined to LA and to BB only (so it
         |         |  | BB |    |      breaks the rotation too)
    y=0  +---------+--+----+----+
         0    5   10 12   17   22
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from shapely.geometry import LineString, Polygon

from mfcl_jax import se2
from mfcl_jax.decision import REASONS, decision_maps, layer, to_frame
from mfcl_jax.decision.lattice import ROTATION, TRANSLATION
from mfcl_jax.decision.maps import pad_maps
from mfcl_jax.decision.symmetry import rotational_motions
from mfcl_jax.floorplan import Door, Floorplan, Room
from mfcl_jax.robot.records import record_of
from mfcl_jax.sim.synthetic import WT, make_run, row_of_rooms, three_rooms, walk
from tests._decision_row import NAMES, ours
from tests._layer import CAPS, J, K, evaluate_runs, evidence_of, lanes_of, maps_of, step, window

G = np.array([22.0, 8.0, np.pi])  # the building's self-motion: half turn about (11, 4)
A = np.array([1.0, -2.0, 0.4])  # hidden ^B T_L


def _rot(pts):
    return [(22.0 - x, 8.0 - y) for x, y in pts]


LA = [(0, 0), (10, 0), (10, 4), (5, 4), (5, 8), (0, 8)]
BA = [(5, 4), (10, 4), (10, 8), (5, 8)]
ROOMS = {
    "LA": LA,
    "BA": BA,
    "S": [(0, 8), (5, 8), (5, 11), (0, 11)],
    "C": [(10, 0), (12, 0), (12, 8), (10, 8)],
    "LB": _rot(LA),
    "BB": _rot(BA),
}
DOORS = [
    (((7, 4), (8, 4)), ("LA", "BA")),
    (((15, 4), (14, 4)), ("LB", "BB")),
    (((2, 8), (3, 8)), ("LA", "S")),
    (((10, 1), (10, 2)), ("LA", "C")),
    (((12, 1), (12, 2)), ("C", "BB")),
]


def _walls():
    """Every room edge as a wall, minus the door openings lying on it."""
    doors = [LineString(seg) for seg, _ in DOORS]
    out = []
    for pts in ROOMS.values():
        ring = list(pts) + [pts[0]]
        for p, q in zip(ring[:-1], ring[1:], strict=True):
            edge = LineString([p, q])
            for d in doors:
                if edge.distance(d) < 1e-9 and edge.intersection(d).length > 0:
                    edge = edge.difference(d)
            parts = getattr(edge, "geoms", [edge])
            out += [np.asarray(g.coords)[[0, -1]] for g in parts if g.length > 1e-9]
    return np.asarray(out, float)


def duplex():
    rooms = tuple(Room(n, Polygon(p).buffer(-WT / 2, join_style="mitre")) for n, p in ROOMS.items())
    doors = tuple(Door(np.asarray(s, float), r) for s, r in DOORS)
    return Floorplan(walls=_walls(), thickness=WT, rooms=rooms, doors=doors, name="duplex")


FP = duplex()
MAPS = maps_of(FP)
INSIDE_A = [[2, 2], [8.5, 2], [7.5, 6], [7.5, 2], [2, 2], [2, 6]]  # LA -> BA -> LA
INTO_S = [[2, 2], [8.5, 2], [7.5, 6], [7.5, 2], [2.5, 6], [2.5, 9.5]]  # ... -> S
BOTH_UNITS = [[2, 2], [8.5, 2], [7.5, 6], [7.5, 2], [11, 1.5], [14.5, 1.5], [14.5, 6]]


def true_wins(k, Y):
    # the truth is every window's champion; its rotated twin trails (tie-broken away).
    return [(Y, 1.0 + 0.01 * k), (np.asarray(se2.compose(G, Y)), 0.95), (Y + [0.3, -4, 0], 0.2)]


def twin_wins(k, Y):
    # the Duplex failure: the front-end consistently prefers the rotated twin unit.
    return [(np.asarray(se2.compose(G, Y)), 1.0 + 0.01 * k), (Y, 0.95)]


def run(path, cands=true_wins):
    return make_run(walk(path), A, K, cands, J=J, fp=FP)


def evaluate(*runs):
    return evaluate_runs(list(runs), MAPS)[0]


def test_rotational_motion_of_the_building():
    mots, support = rotational_motions(FP, 0.8)
    assert mots.shape == (1, 3)
    np.testing.assert_allclose(mots[0, :2], G[:2], atol=1e-6)
    assert abs(abs(mots[0, 2]) - np.pi) < 1e-9
    assert support[0] == 4  # LA<->LB, BA<->BB; S and C have no image
    m = decision_maps(FP).sym
    assert m.motions.shape == (1, 8, 3) and m.motions_mask.sum() == 1
    # translated copies and bare rooms give no rotational motion
    for fp in (row_of_rooms(), three_rooms()):
        assert not decision_maps(fp).sym.motions_mask.any()


def test_quarter_turn_pair_gives_a_motion_and_its_inverse():
    ell = Polygon([(0, 0), (6, 0), (6, 3), (3, 3), (3, 6), (0, 6)])
    r90 = Polygon([(20 - y, x) for x, y in ell.exterior.coords])  # R(90 deg) then (20, 0)
    walls = np.array([[[0, 0], [0, 6]], [[14, 0], [20, 0]]], float)
    fp = Floorplan(walls=walls, thickness=WT, rooms=(Room("a", ell), Room("b", r90)))
    mots, support = rotational_motions(fp, 0.8)
    assert sorted(np.rad2deg(mots[:, 2]).round().tolist()) == [-90.0, 90.0]
    g = mots[np.argmax(mots[:, 2])]
    np.testing.assert_allclose(g, [20.0, 0.0, np.pi / 2], atol=1e-6)
    assert support.tolist() == [1, 1]
    capped = pad_maps(decision_maps(fp, max_motions=2), (100, 240), 2, n_motions=4).sym
    assert capped.motions.shape == (1, 4, 3) and capped.motions_mask.sum() == 2
    with pytest.raises(ValueError, match="rotational motions"):
        decision_maps(fp, max_motions=1)


def test_inside_one_unit_is_ambiguous_rotation_until_the_scans_tell_the_units_apart():
    """Inside unit A every window also fits the rotated twin unit B: AMBIGUOUS(rotation).
    The LiDAR sees, through the doors, the storage and corridor that have no image; once the
    scans rule the twin out, the run whose champions are true commits (correctly), and the
    run whose champions are the twin (the Duplex failure) ends "winner contradicted": never a
    commit to the twin. Without the probe the latter commits to the twin."""
    out = evaluate(run(INSIDE_A), run(INSIDE_A, twin_wins))
    no_probe = NAMES.index("no_probe")
    for r, anchor in ((0, A), (1, np.asarray(se2.compose(G, A)))):
        d = ours(jax.tree.map(lambda x, r=r: x[r : r + 1], out))
        rot = (d.state == 1) & (d.kind == ROTATION)
        # the probe names the twin before the scans tell the units apart (with the certification's
        # blocks, the view through a door rules it out within a window
        # or two when the champions are true)
        assert rot.sum() >= (1 if r == 0 else 3), (d.state.tolist(), d.kind.tolist())
        assert (d.kind != TRANSLATION).all()
        assert out.state[r, -1, no_probe] == 2  # without the probe it commits
        assert float(se2.distance_pair(out.anchor[r, -1, no_probe], anchor)[0]) < 0.05
        for k in np.nonzero(rot)[0]:
            assert d.probe_alias[k] and d.probe_c[k] >= 0.5  # the gate admits the twin
            np.testing.assert_allclose(d.tau[k], 0.0)
            dxy, dth = se2.distance_pair(d.alias_motion[k], G)
            assert float(dxy) < 1e-3 and float(dth) < 1e-4
        if r == 0:
            assert d.state[-1] == 2 and float(se2.distance_pair(d.anchor[-1], A)[0]) < 0.05
        else:
            assert (d.state != 2).all() and REASONS[int(d.reason[-1])] == "winner contradicted"
    df = to_frame(out, lanes_of()[2])
    row = df[(df.run == 0) & (df.k == 3) & (df.policy == "ours")].iloc[0]
    assert row.kind == "rotation" and np.isnan(row.tau_x) and np.isnan(row.tau_y)
    # the table lists the twin's anchor as the competing explanation
    twin = np.asarray(se2.compose(G, np.asarray([row.x, row.y, np.deg2rad(row.yaw_deg)])))
    assert abs(row.alt_x - twin[0]) < 1e-2 and abs(row.alt_y - twin[1]) < 1e-2
    done = df[(df.policy == "ours") & (df.state != "AMBIGUOUS")]
    assert done.alt_x.isna().all()


@pytest.mark.parametrize("cands", [true_wins, twin_wins], ids=["true_wins", "twin_wins"])
@pytest.mark.parametrize("path", [INTO_S, BOTH_UNITS], ids=["storage", "both_units"])
def test_symmetry_breaking_structure_commits(path, cands):
    # once the twin's image of the path leaves the plan, the gate drops the twin champions too
    d = ours(evaluate(run(path, cands)))
    assert d.state[-1] == 2, (d.state.tolist(), d.kind.tolist())
    if cands is twin_wins:  # AMBIGUOUS(rotation) while the twin wins, then COMMIT to the truth
        assert (d.kind == ROTATION).any()
    assert float(se2.distance_pair(d.anchor[-1], A)[0]) < 0.05
    np.testing.assert_allclose(d.alias_motion[-1], 0.0)


def test_c2_immunity_of_the_rotation_verdict():
    base = run(INSIDE_A)
    flooded = {k: np.array(v, copy=True) for k, v in base.items()}
    rng = np.random.default_rng(3)
    j0 = int(base["mask"][0].sum())
    for k in range(K):
        top = base["score"][k][base["mask"][k]].max()
        m = J - j0
        near_twin = base["H"][k, 1] + rng.normal(0, 0.3, (m, 3)) * [1, 1, 0.05]
        flooded["H"][k, j0:] = near_twin
        flooded["score"][k, j0:] = top * rng.uniform(0.0, 0.999, m)
        flooded["mask"][k, j0:] = True
    out = evaluate(base, flooded)
    a, b = (ours(jax.tree.map(lambda x, r=r: x[r : r + 1], out)) for r in (0, 1))
    for f in ("state", "kind", "b1", "b2", "margin", "n_champions"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    np.testing.assert_allclose(a.anchor, b.anchor, atol=1e-4)
    # the certification's rival may be a flooded copy of the twin (a runner-up), the same
    # motion up to the flood's jitter
    dxy, dth = se2.distance_pair(a.alias_motion, b.alias_motion)
    assert float(np.max(dxy)) < 1e-3 and float(np.max(dth)) < 1e-3


@pytest.mark.parametrize("path", [INSIDE_A, INTO_S], ids=["inside_a", "storage"])
def test_robot_equals_batch_with_rotation(path):
    """One ``update`` per window (the robot) decides as the batch scan, and the decisions
    file line says the rotation: no period, the twin listed as the alternative."""
    r = run(path)
    out = ours(evaluate(r))
    p, lanes, spec = lanes_of(ours=("ours",), baselines=False)
    maps = jax.tree.map(lambda a: a[0], MAPS)
    state = layer.init(maps, p.as_arrays(), CAPS, jax.tree.map(jnp.asarray, lanes), spec)
    ev = evidence_of(r)
    kinds = []
    for k in range(K):
        state, d = step()(state, window(ev, k))
        d = jax.tree.map(lambda a: np.asarray(a[0]), d)
        assert int(d.state) == out.state[k] and int(d.kind) == out.kind[k]
        np.testing.assert_allclose(d.anchor, out.anchor[k], atol=1e-4)
        line = record_of(d, k + 1, float(k), r["X"][k])
        if int(d.kind) == ROTATION:
            assert line["symmetry"] == "rotation" and line["tau"] is None
            assert np.allclose(np.asarray(d.alias_motion)[:2], G[:2], atol=1e-3)
            # the competing explanation listed is the twin, g T*, as in the batch
            twin = np.asarray(se2.compose(G, np.asarray(d.anchor, np.float32)))
            dxy, dth = se2.distance_pair(np.asarray(d.competitor), twin)
            assert float(dxy) < 1e-2 and float(dth) < 1e-3
            np.testing.assert_allclose(d.competitor, out.competitor[k], atol=1e-4)
            assert len(line["alternatives"]) == 2
        if line["state"] != "AMBIGUOUS":
            assert line["alternatives"] is None
        kinds.append(line["symmetry"])
    assert kinds[-1] is None and "rotation" in kinds  # ambiguous until the scans tell
