"""Every storey at once: congruent storeys share one place, a commit names the storey, and a
walk on a floor identical to another never commits (AMBIGUOUS(storey) or DEFER)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from mfcl_jax.cli import main
from mfcl_jax.floorplan import FloorplanError, load_floorplan
from mfcl_jax.floorplan.geojson_write import floorplan_to_geojson, save_geojson
from mfcl_jax.floorplan.load import load_building
from mfcl_jax.floorplan.storeys import congruence, stack_storeys
from mfcl_jax.io import read_decisions
from mfcl_jax.sim.families.tower import make_tower


@pytest.fixture(scope="module")
def towers():
    return {k: make_tower(k, 0, 4) for k in ("typical", "one_room", "rotated")}


def test_congruent_storeys_share_a_place_and_map_back(towers):
    typ = towers["typical"]
    plan, st = stack_storeys(typ.storeys, name=typ.name)
    assert st.names == ("G", "L1", "L2", "L3")
    assert list(st.tile) == [0, 1, 1, 1] and st.n_tiles == 2
    assert not st.shared(0) and st.shared(1) and st.group(1) == [1, 2, 3]
    assert typ.congruent == [False, True, True, True]
    # every room once per place, named after the storeys that share it
    g_rooms, l_rooms = len(typ.storeys[0][1].rooms), len(typ.storeys[1][1].rooms)
    assert len(plan.rooms) == g_rooms + l_rooms
    assert all(n.startswith(("G/", "L1+L2+L3/")) for n in plan.room_names)
    # a pose on L2 goes to the stacked plan and back unchanged
    pose = np.array([3.0, 2.0, 0.4])
    c, s = math.cos(st.place[2][2]), math.sin(st.place[2][2])
    stacked = (st.place[2][0] + c * pose[0] - s * pose[1],
               st.place[2][1] + s * pose[0] + c * pose[1], st.place[2][2] + pose[2])  # fmt: skip
    assert st.tile_at(*stacked[:2]) == 1
    assert np.allclose(st.to_storey(2, stacked), pose)
    # the places lie GAP apart: no window reaches from one to the other
    b = st.boxes
    assert b[1, 1] - b[0, 3] >= 12.0 - 1e-9 or b[1, 0] - b[0, 2] >= 12.0 - 1e-9


def test_congruence_sees_a_half_turn_and_a_stub(towers):
    rot = towers["rotated"]
    g = congruence(rot.storeys[1][1], rot.storeys[2][1])
    assert g is not None and abs(abs(g[2]) - math.pi) < 1e-9  # L2 is L1 turned by 180 deg
    assert rot.congruent == [False, True, True, True]
    one = towers["one_room"]
    # floors identical but for one 1.2 m wall stub each: no two are congruent
    assert one.congruent == [False] * len(one.storeys)
    assert congruence(one.storeys[0][1], one.storeys[1][1]) is None
    _, st = stack_storeys(one.storeys)
    assert st.n_tiles == len(one.storeys)


def _levels(storeys, path):
    feats = []
    for name, fp in storeys:
        for f in floorplan_to_geojson(fp)["features"]:
            f.setdefault("properties", {})["level"] = name
            feats.append(f)
    path.write_text(json.dumps({"type": "FeatureCollection", "features": feats}))
    return path


def test_geojson_levels_and_several_files_are_storeys(towers, tmp_path):
    typ = towers["typical"]
    path = _levels(typ.storeys[:3], tmp_path / "tower.geojson")
    plan = load_floorplan(path)
    assert plan.storeys.names == ("G", "L1", "L2") and plan.storeys.n_tiles == 2
    one = load_floorplan(path, storey="L1")
    assert one.storeys is None and len(one.rooms) == len(typ.storeys[1][1].rooms)
    with pytest.raises(FloorplanError, match=r"unknown level 'L9'; levels: G, L1, L2"):
        load_floorplan(path, storey="L9")
    data = json.loads(path.read_text())
    del data["features"][3]["properties"]["level"]
    (tmp_path / "mixed.geojson").write_text(json.dumps(data))
    with pytest.raises(FloorplanError, match=r"feature #3 has no 'level' property"):
        load_floorplan(tmp_path / "mixed.geojson")
    flat = save_geojson(typ.storeys[0][1], tmp_path / "flat.geojson")
    with pytest.raises(FloorplanError, match="no feature has a 'level'"):
        load_floorplan(flat, storey="G")
    # one file per storey (as ROS maps come): named by the file's stem
    a = save_geojson(typ.storeys[0][1], tmp_path / "ground.geojson")
    b = save_geojson(typ.storeys[1][1], tmp_path / "first.geojson")
    both = load_building([a, b])
    assert both.storeys.names == ("ground", "first")
    assert load_building([a, b], storey="first").storeys.given == 1  # still both weighed
    with pytest.raises(FloorplanError, match=r"storey 'third': not one of the plans"):
        load_building([a, b], storey="third")


def test_a_walk_on_a_typical_floor_never_commits_and_the_ground_floor_names_itself(
    towers, tmp_path, capsys
):
    """``mfcl localize`` of two walks against a three-storey GeoJSON (levels): on the ground
    floor the layer commits and names ``G``; on L1, identical to L2, it never commits and says
    AMBIGUOUS(storey) with both storeys; ``mfcl evaluate --storey`` judges the storey."""
    from mfcl_jax.sources.simulated import simulate_dataset

    typ = towers["typical"]
    plan = _levels(typ.storeys[:3], tmp_path / "tower.geojson")
    data = tmp_path / "data"
    for s, name in ((0, "G"), (1, "L1")):
        scene = typ.scenes[s]
        wp = scene.trajectories[sorted(scene.trajectories)[0]]
        simulate_dataset(scene.floorplan, wp, data / name, seed=s)
    out = tmp_path / "out"
    assert main(["localize", str(data), "--floorplan", str(plan), "--out-dir", str(out)]) == 0
    text = capsys.readouterr().out
    g, l1 = read_decisions(out / "G.jsonl"), read_decisions(out / "L1.jsonl")
    commits = [d for d in g if d["state"] == "COMMIT"]
    assert commits and all(d["storey"] == "G" and d["storeys"] == ["G"] for d in commits)
    assert "on storey 'G'" in text
    assert not any(d["state"] == "COMMIT" for d in l1)
    amb = [d for d in l1 if d["symmetry"] == "storey"]
    assert amb and all(d["storeys"] == ["L1", "L2"] and d["storey"] is None for d in amb)
    assert l1[-1]["symmetry"] == "storey"
    alt = amb[-1]["alternatives"]
    assert [a["storey"] for a in alt[:2]] == ["L1", "L2"]
    # the same spot on both floors (identical, unmoved): the pose is the walk's
    assert math.hypot(alt[0]["x"] - alt[1]["x"], alt[0]["y"] - alt[1]["y"]) < 1e-6
    dec = str(out / "G.jsonl")
    assert main(["evaluate", str(data / "G"), "--decisions", dec, "--storey", "G"]) == 0
    assert main(["evaluate", str(data / "G"), "--decisions", dec, "--storey", "L1"]) != 0
    capsys.readouterr()


def _decision(state: int, anchor, competitor=None):
    """A host ``Decision``-like record of one lane (what ``records.record_of`` reads)."""
    from types import SimpleNamespace

    return SimpleNamespace(
        state=state, kind=0, anchor=np.asarray(anchor, np.float64), tau=np.zeros(2), b1=3,
        b2=0, margin=3, reason=0, competitor=np.zeros(3) if competitor is None
        else np.asarray(competitor, np.float64), has_competitor=competitor is not None,
        llr=np.nan,
    )  # fmt: skip


def test_a_storey_named_is_weighed_with_the_others(towers, tmp_path):
    """``--storey`` on a plan of several storeys: every storey is still stacked and the named
    one marked given; its place (shared with its congruent twins) names it; a commit on another
    storey's place is DEFER ``other storey``, never a pose; the decision maps' shared flag
    spares the given storey's place."""
    from mfcl_jax.decision.maps import decision_maps
    from mfcl_jax.decision.outcome import COMMIT
    from mfcl_jax.io.decisions import decision_line
    from mfcl_jax.robot.records import OTHER_STOREY, record_of

    typ = towers["typical"]
    path = _levels(typ.storeys, tmp_path / "tower.geojson")
    plan = load_building([path], storey="L2")
    st = plan.storeys
    assert st.names == ("G", "L1", "L2", "L3") and st.given == 2
    assert not st.shared(1)  # L1+L2+L3 share a place; L2 is given, so it names it
    assert not decision_maps(plan).shared.any()
    free = load_building([path]).storeys
    assert free.given == -1 and free.shared(1)
    assert decision_maps(load_building([path])).shared.sum() == len(typ.storeys[1][1].rooms)
    X = np.zeros(3)

    def at(s, x, y):  # the anchor placing the robot (X = identity) at (x, y) on storey s
        return (st.place[s][0] + x, st.place[s][1] + y, st.place[s][2])

    on_l2 = record_of(_decision(COMMIT, at(2, 3.0, 2.0)), 1, 0.0, X, storeys=st)
    assert on_l2["state"] == "COMMIT" and on_l2["storey"] == "L2"
    assert np.allclose([on_l2["pose"]["x"], on_l2["pose"]["y"]], [3.0, 2.0])
    on_g = record_of(_decision(COMMIT, at(0, 3.0, 2.0)), 2, 1.0, X, storeys=st)
    assert on_g["state"] == "DEFER" and on_g["reason"] == OTHER_STOREY
    assert on_g["pose"] is None and on_g["anchor"] is None and on_g["storeys"] == ["G"]
    decision_line(on_l2), decision_line(on_g)  # both are valid lines
    # without a storey named, a commit on the shared place names none
    shared = record_of(_decision(COMMIT, at(2, 3.0, 2.0)), 3, 2.0, X, storeys=free)
    assert shared["state"] == "AMBIGUOUS" and shared["symmetry"] == "storey"
    assert shared["storeys"] == ["L1", "L2", "L3"] and shared["storey"] is None
    decision_line(shared)


def test_the_benchmark_scores_a_shared_place_as_naming_no_storey(towers):
    """The benchmark's tower rows: an anchor on the place congruent storeys share is never a
    correct commit (whatever the truth), and a walk on such a storey is not identifiable."""
    import pandas as pd

    from mfcl_jax.bench.run import _storey_label
    from mfcl_jax.score.decisions import _storey_rule
    from mfcl_jax.score.identifiability import RunLabel
    from mfcl_jax.sources.recording import Recording

    plan, st = stack_storeys(towers["typical"].storeys)
    c_g = st.boxes[0, :2] + 2.0  # inside the ground floor's place
    c_l = st.boxes[1, :2] + 2.0  # inside the place L1-L3 share
    scored = pd.DataFrame({"placed_x": [c_g[0], c_l[0], np.nan],
                           "placed_y": [c_g[1], c_l[1], np.nan],
                           "correct": [True, True, False]})  # fmt: skip
    assert _storey_rule(scored, plan)["correct"].tolist() == [True, False, False]
    lab = RunLabel(True, 3, np.ones(5, bool), 0, None)
    rec = Recording("t/L1/A", plan, None, None, {"congruent": True})
    out = _storey_label(rec, lab)
    assert not out.identifiable and out.oracle_k is None and not out.identifiable_k.any()
    assert _storey_label(Recording("t/G/A", plan, None, None, {}), lab) is lab


def test_the_mcap_draws_a_commit_on_its_storey(towers, tmp_path):
    """``--viz`` with a plan of several storeys: the decisions file gives the pose in the
    storey's own frame; the MCAP draws the stacked plan, so the pose is drawn where that
    storey lies in it (read back with the mcap reader)."""
    from types import SimpleNamespace

    from mfcl_jax.decision.outcome import COMMIT
    from mfcl_jax.robot.records import record_of
    from mfcl_jax.robot.viz import VizWriter
    from tests._mcap import _read, _xyyaw

    plan, st = stack_storeys(towers["typical"].storeys)
    s = 0  # the ground floor (a place of its own)
    anchor = (st.place[s][0] + 3.0, st.place[s][1] + 2.0, st.place[s][2] + 0.5)
    rec = record_of(_decision(COMMIT, anchor), 1, 1.0, np.zeros(3), storeys=st)
    assert rec["storey"] == "G" and np.allclose([rec["pose"]["x"], rec["pose"]["y"]], [3, 2])
    viz = VizWriter(tmp_path / "v.mcap", plan, start=0.0)
    viz.add(SimpleNamespace(k=1, t=1.0, X=np.zeros(3), segment=0, points=None), rec)
    msgs = _read(viz.close())
    (pose,) = msgs["/mfcl/pose"][0][2]["poses"]
    x, y, yaw_deg = _xyyaw(pose)
    assert np.allclose([x, y, math.radians(yaw_deg)], anchor, atol=1e-9)
    assert st.tile_at(*_xyyaw(pose)[:2]) == int(st.tile[s])
