"""``mfcl simulate -> localize -> evaluate`` round trip, and every bad input: non-zero exit,
a message naming the file, no partial output."""

import json
import shutil

import numpy as np
import pytest

from mfcl_jax.cli import main
from mfcl_jax.floorplan import save_geojson
from mfcl_jax.io import read_decisions, read_tum
from mfcl_jax.robot.records import robot_pose
from mfcl_jax.sim.scenes import symmetric_bays

# R1 -> door line -> R4 of the symmetric bays (the plan of the other ``mfcl localize`` tests,
# so one compiled robot step serves them all): 109 scans, 11 windows of 6 m; DEFER (the bays'
# 7.3 m period) until the walk nears the far wall, the last windows COMMIT.
WAYPOINTS = [(1.0, 4.2), (3.0, 1.8), (27.0, 1.8)]


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    root = tmp_path_factory.mktemp("cli")
    plan = root / "bays.geojson"
    save_geojson(symmetric_bays().floorplan, plan)
    wp = root / "wp.csv"
    wp.write_text("x,y\n" + "\n".join(f"{x},{y}" for x, y in WAYPOINTS) + "\n")
    ds = root / "ds"
    assert (
        main(
            [
                "simulate",
                "--floorplan",
                str(plan),
                "--trajectory",
                str(wp),
                "--out",
                str(ds),
                "--seed",
                "3",
            ]
        )
        == 0
    )
    return root, plan, wp, ds


def test_round_trip(sim, capsys):
    root, _, _, ds = sim
    for name in ("floorplan.geojson", "odometry.tum", "groundtruth.tum", "scans"):
        assert (ds / name).exists()
    out = root / "dec.jsonl"
    assert main(["localize", str(ds), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "k=  1" in text and "windows" in text
    lines = out.read_text().splitlines()
    decs = read_decisions(out)  # validates the schema
    assert len(decs) == len(lines) == 11
    keys = ["k", "t", "state", "anchor", "symmetry", "tau", "B1", "B2", "margin"]
    ot, odo = read_tum(ds / "odometry.tum")
    status = [line for line in text.splitlines() if line.startswith("k=")]
    for i, (d, line, st) in enumerate(zip(decs, lines, status, strict=True), 1):
        # k over the whole recording and its odometry segment first (no jump here: 0).
        assert list(json.loads(line)) == ["k", "segment", *keys[1:], "pose", "reason",
                                          "alternatives"]  # fmt: skip
        assert d["k"] == i and d["segment"] == 0 and isinstance(d["t"], float)
        assert (d["anchor"] is None) == (d["state"] != "COMMIT") == (d["pose"] is None)
        assert (d["alternatives"] is None) == (d["state"] != "AMBIGUOUS")
        if d["state"] == "COMMIT":  # the robot's pose now: T* composed with the odometry
            a, p = d["anchor"], d["pose"]
            X = odo[np.argmin(np.abs(ot - d["t"]))]
            want = robot_pose((a["x"], a["y"], np.deg2rad(a["yaw_deg"])), X)
            np.testing.assert_allclose([p["x"], p["y"]], want[:2], atol=1e-9)
            assert f"robot at x={p['x']:.2f} m, y={p['y']:.2f} m" in st
        elif d["reason"]:
            assert f"{d['reason']} (" in st
    assert [d["t"] for d in decs] == sorted(d["t"] for d in decs)
    assert main(["evaluate", str(ds), "--decisions", str(out), "--windows"]) == 0
    table = capsys.readouterr().out
    assert "first commit k" in table and "final state" in table
    # The commit is scored (a false one would show as FALSE).
    assert decs[-1]["state"] == "COMMIT" and "correct" in table


def _fails(argv, capsys, *names):
    assert main(argv) != 0
    err = capsys.readouterr().err
    assert err.startswith("mfcl: error:") and "Traceback" not in err
    for n in names:
        assert str(n) in err, err
    return err


@pytest.mark.parametrize(
    "body, where",
    [
        ("x,y\n1,2\n3,abc\n", "line 3: field y"),
        ("1,2\n3\n", "line 2: expected 2 fields"),
        ("1,2\n", "at least 2 waypoints"),
        ("1,2\nnan,4\n", "line 2: field x"),
    ],
)
def test_simulate_bad_csv(sim, tmp_path, capsys, body, where):
    _, plan, _, _ = sim
    wp = tmp_path / "bad.csv"
    wp.write_text(body)
    out = tmp_path / "out"
    _fails(
        ["simulate", "--floorplan", str(plan), "--trajectory", str(wp), "--out", str(out)],
        capsys,
        wp,
        where,
    )
    assert not out.exists() and not any(p.name.startswith(".out") for p in tmp_path.iterdir())


def test_simulate_bad_inputs(sim, tmp_path, capsys):
    _, plan, wp, ds = sim
    through_wall = tmp_path / "wall.csv"
    through_wall.write_text("4,5\n10,5\n")  # crosses the R1/R2 partition at x = 7.3
    _fails(
        [
            "simulate",
            "--floorplan",
            str(plan),
            "--trajectory",
            str(through_wall),
            "--out",
            str(tmp_path / "o"),
        ],
        capsys,
        through_wall,
        "wall",
    )
    _fails(
        [
            "simulate",
            "--floorplan",
            str(tmp_path / "no.geojson"),
            "--trajectory",
            str(wp),
            "--out",
            str(tmp_path / "o"),
        ],
        capsys,
        "no.geojson",
    )
    _fails(
        ["simulate", "--floorplan", str(plan), "--trajectory", str(wp), "--out", str(ds)],
        capsys,
        ds,
        "already exists",
    )
    assert not (tmp_path / "o").exists()


def test_localize_bad_inputs(sim, tmp_path, capsys):
    _, plan, _, ds = sim
    out = tmp_path / "dec.jsonl"
    _fails(["localize", str(tmp_path / "nowhere"), "--out", str(out)], capsys, "nowhere")
    broken = tmp_path / "broken"
    shutil.copytree(ds, broken)
    (broken / "odometry.tum").write_text("0 1 2 3\n")
    _fails(["localize", str(broken), "--out", str(out)], capsys, broken / "odometry.tum")
    shutil.rmtree(broken)
    shutil.copytree(ds, broken)
    scan = sorted((broken / "scans").iterdir())[3]
    scan.rename(scan.with_name("scan_three.pcd"))  # a scan's name is its time stamp
    _fails(["localize", str(broken), "--out", str(out)], capsys, "scan_three.pcd")
    _fails(
        ["localize", str(ds), "--floorplan", str(tmp_path / "x.ifc"), "--out", str(out)],
        capsys,
        "x.ifc",
    )
    _fails(
        [
            "localize",
            "--bag",
            str(tmp_path / "none.bag"),
            "--floorplan",
            str(plan),
            "--out",
            str(out),
        ],
        capsys,
        "none.bag",
    )
    _fails(
        ["localize", "--bag", str(tmp_path / "none.bag"), "--out", str(out)], capsys, "--floorplan"
    )
    _fails(["localize", str(ds), "--d-s", "-1", "--out", str(out)], capsys, "--d-s")
    _fails(["localize", str(ds), "--out", str(out), "--out-dir", str(tmp_path)], capsys,
           "--out", "--out-dir")  # fmt: skip
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".dec")]


def test_evaluate_bad_inputs(sim, tmp_path, capsys):
    _, _, _, ds = sim
    nogt = tmp_path / "nogt"
    shutil.copytree(ds, nogt)
    (nogt / "groundtruth.tum").unlink()
    dec = tmp_path / "dec.jsonl"
    dec.write_text(
        json.dumps(
            {
                "k": 1,
                "t": 12.0,
                "state": "DEFER",
                "anchor": None,
                "symmetry": None,
                "tau": None,
                "B1": 0,
                "B2": 0,
                "margin": 0,
            }
        )
        + "\n"
    )
    _fails(["evaluate", str(nogt), "--decisions", str(dec)], capsys, "groundtruth.tum")
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"k": 1, "state": "MAYBE"}\n')
    _fails(["evaluate", str(ds), "--decisions", str(bad)], capsys, f"{bad}:1")
    late = tmp_path / "late.jsonl"
    late.write_text(dec.read_text().replace("12.0", "1e6"))
    _fails(["evaluate", str(ds), "--decisions", str(late)], capsys, late, "t=")


def test_waypoints_header_and_comments(tmp_path):
    from mfcl_jax.sources.walks import read_waypoints

    p = tmp_path / "w.csv"
    p.write_text("# a comment\nx, y\n1, 2\n\n3,4\n")
    np.testing.assert_allclose(read_waypoints(p), [[1, 2], [3, 4]])
