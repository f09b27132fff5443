"""TUM, PCD, dataset-folder and decision-log round trips and their error messages."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import box

from mfcl_jax.floorplan import Door, Floorplan, FloorplanError, Room, load_floorplan
from mfcl_jax.io import (
    DataError,
    read_decisions,
    read_pcd,
    read_tum,
    write_decisions,
    write_pcd,
    write_tum,
)
from mfcl_jax.sources import load_dataset, write_dataset


def _plan() -> Floorplan:
    walls = np.array(
        [
            [[0, 0], [8, 0]],
            [[8, 0], [8, 4]],
            [[8, 4], [0, 4]],
            [[0, 4], [0, 0]],
            [[4, 0], [4, 1.5]],
            [[4, 2.5], [4, 4]],
        ],
        float,
    )
    return Floorplan(
        walls=walls,
        thickness=0.15,
        rooms=(Room("a", box(0, 0, 4, 4)), Room("b", box(4, 0, 8, 4))),
        doors=(Door(np.array([[4, 1.5], [4, 2.5]]), ("a", "b")),),
    )


def _leftovers(parent, name):
    return [p.name for p in parent.iterdir() if p.name.startswith(f".{name}")]


def test_tum_round_trip(tmp_path):
    t = np.array([0.0, 0.1, 0.25, 1.5])
    poses = np.array([[0, 0, 0], [1, 2, 0.5], [-3, 1, math.pi - 1e-3], [2, 2, -2.0]])
    path = write_tum(tmp_path / "o.tum", t, poses)
    t2, p2, s2 = read_tum(path, with_strings=True)
    np.testing.assert_allclose(t2, t)
    np.testing.assert_allclose(p2, poses, atol=1e-7)
    assert s2 == ["0", "0.1", "0.25", "1.5"]


@pytest.mark.parametrize(
    "body, words",
    [
        ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n", ["o.tum:2", "8 columns", "got 7"]),
        ("0 0 0 0 0 0 0 1\n1 nan 0 0 0 0 0 1\n", ["o.tum:2", "non-finite"]),
        ("0 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", ["o.tum:3", "does not increase"]),
        ("0 0 0 0 0 0 0 1\n0 1 0 0 0 0 0 1\n", ["o.tum:2", "does not increase"]),
        ("0 0 0 zero 0 0 0 1\n", ["o.tum:1", "not a number"]),
    ],
)
def test_tum_errors(tmp_path, body, words):
    (tmp_path / "o.tum").write_text(body)
    with pytest.raises(DataError) as e:
        read_tum(tmp_path / "o.tum")
    for w in words:
        assert w in str(e.value)


@pytest.mark.parametrize("binary", [True, False])
def test_pcd_round_trip(tmp_path, binary):
    pts = np.random.default_rng(0).normal(size=(50, 2)) * 5
    path = write_pcd(tmp_path / "s.pcd", pts, binary=binary)
    back, dropped = read_pcd(path, return_dropped=True)
    np.testing.assert_allclose(back, pts, atol=1e-5)
    assert dropped == 0


def test_pcd_nan_points_dropped_and_counted(tmp_path):
    pts = np.array([[1, 2, 0], [np.nan, 1, 0], [3, np.inf, 0], [4, 5, np.nan]], float)
    for binary in (True, False):
        path = write_pcd(tmp_path / f"n{binary}.pcd", pts, binary=binary)
        xy, dropped = read_pcd(path, return_dropped=True)
        assert dropped == 2  # a NaN z does not make the planar point unusable
        np.testing.assert_allclose(xy, [[1, 2], [4, 5]])


def test_pcd_extra_fields_and_wrong_fields(tmp_path):
    head = (
        "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
        "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
    )
    (tmp_path / "i.pcd").write_text(head + "1 2 3 9\n4 5 6 9\n")
    np.testing.assert_allclose(read_pcd(tmp_path / "i.pcd"), [[1, 2], [4, 5]])
    bad = head.replace("FIELDS x y z", "FIELDS x v z")
    (tmp_path / "b.pcd").write_text(bad + "1 2 3 9\n")
    with pytest.raises(DataError, match=r"b\.pcd: missing field 'y'"):
        read_pcd(tmp_path / "b.pcd")
    (tmp_path / "t.pcd").write_text(head.replace("DATA ascii", "DATA binary") + "xx")
    with pytest.raises(DataError, match=r"t\.pcd: binary data truncated"):
        read_pcd(tmp_path / "t.pcd")


def _write(tmp_path, **kw):
    rng = np.random.default_rng(1)
    t = np.array([0.0, 0.5, 1.0])
    scans = [rng.normal(size=(20, 2)) for _ in t]
    odom = np.array([[1, 1, 0], [1.5, 1, 0.1], [2, 1.2, 0.2]])
    gt = odom + [0.1, 0.0, 0.0]
    out = write_dataset(tmp_path / "ds", _plan(), t, scans, odom, groundtruth=gt, **kw)
    return out, t, scans, odom, gt


def test_dataset_round_trip(tmp_path):
    out, t, scans, odom, gt = _write(tmp_path)
    ds = load_dataset(out)
    assert len(ds) == 3 and ds.time_strings == ("0", "0.5", "1")
    np.testing.assert_allclose(ds.times, t)
    np.testing.assert_allclose(ds.odometry, odom, atol=1e-7)
    np.testing.assert_allclose(ds.groundtruth, gt, atol=1e-7)
    for a, b in zip(ds.scans, scans, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-5)
    assert ds.floorplan.room_names == ("a", "b") and ds.floorplan.adjacency[0, 1]
    assert _leftovers(tmp_path, "ds") == []


def test_dataset_write_is_atomic(tmp_path):
    _write(tmp_path)
    with pytest.raises(DataError, match="already exists"):
        _write(tmp_path)
    # A failure half way leaves neither a partial folder nor a temporary one.
    with pytest.raises(DataError):
        write_dataset(
            tmp_path / "bad",
            _plan(),
            [0.0, 1.0],
            [np.zeros((3, 2))] * 2,
            [[0, 0, 0], [np.nan, 0, 0]],
        )
    assert not (tmp_path / "bad").exists() and _leftovers(tmp_path, "bad") == []
    _write(tmp_path, overwrite=True)
    assert len(load_dataset(tmp_path / "ds")) == 3


def test_dataset_scan_names_are_times_as_numbers(tmp_path):
    # Issue 29: a scan named 0.50.pcd is the odometry line 0.5 (refused before).
    out, t, _, odom, _ = _write(tmp_path)
    (out / "scans" / "0.5.pcd").rename(out / "scans" / "0.50.pcd")
    ds = load_dataset(out)
    assert ds.time_strings == ("0", "0.50", "1")
    np.testing.assert_allclose(ds.odometry, odom, atol=1e-7)
    (out / "scans" / "x.pcd").write_bytes((out / "scans" / "1.pcd").read_bytes())
    with pytest.raises(DataError, match=r"x\.pcd: a scan file is named by its time.*got 'x'"):
        load_dataset(out)


def test_dataset_non_monotonic_odometry(tmp_path):
    out, *_ = _write(tmp_path)
    lines = (out / "odometry.tum").read_text().splitlines()
    lines[2], lines[3] = lines[3], lines[2]
    (out / "odometry.tum").write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"odometry\.tum:4: timestamp 0\.5 does not increase"):
        load_dataset(out)


def test_geojson_without_rooms(tmp_path):
    p = tmp_path / "f.geojson"
    p.write_text(
        '{"type": "FeatureCollection", "features": [{"type": "Feature", '
        '"properties": {"kind": "wall"}, "geometry": {"type": "LineString", '
        '"coordinates": [[0, 0], [1, 0]]}}]}'
    )
    with pytest.raises(FloorplanError, match=r"f\.geojson: no 'room' features"):
        load_floorplan(p)


def test_load_floorplan_dispatch_errors(tmp_path):
    (tmp_path / "plan.dxf").write_text("x")
    with pytest.raises(FloorplanError, match=r"plan\.dxf: unknown floor-plan format '\.dxf'"):
        load_floorplan(tmp_path / "plan.dxf")
    with pytest.raises(FloorplanError, match="file not found"):
        load_floorplan(tmp_path / "nope.ifc")
    (tmp_path / "broken.ifc").write_text("ISO-10303-21;\nthis is not IFC\nEND-ISO-10303-21;\n")
    with pytest.raises(FloorplanError, match=r"broken\.ifc: not a readable IFC file"):
        load_floorplan(tmp_path / "broken.ifc")


def test_rosmap_errors(tmp_path):
    from PIL import Image

    img = np.full((40, 50), 254, np.uint8)
    img[5, 5:45] = img[35, 5:45] = img[5:36, 5] = img[5:36, 45] = 0
    img[5:36, 25] = 0
    img[17:23, 25] = 254  # a 0.6 m door
    Image.fromarray(img).save(tmp_path / "m.png")
    good = "image: m.png\nresolution: 0.1\norigin: [1.0, 2.0, 0.0]\nnegate: 0\n"
    (tmp_path / "m.yaml").write_text(good + "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    fp = load_floorplan(tmp_path / "m.yaml")
    assert len(fp.rooms) == 2 and fp.adjacency[0, 1]
    assert abs(fp.bounds[0] - 1.5) < 0.11 and abs(fp.bounds[1] - 2.5) < 0.11
    (tmp_path / "r.yaml").write_text(good.replace("0.1", "-0.1"))
    with pytest.raises(FloorplanError, match=r"r\.yaml: bad field resolution=-0\.1"):
        load_floorplan(tmp_path / "r.yaml")
    (tmp_path / "o.yaml").write_text(good.replace("[1.0, 2.0, 0.0]", "[1.0, 2.0]"))
    with pytest.raises(FloorplanError, match=r"bad field origin=\[1\.0, 2\.0\]"):
        load_floorplan(tmp_path / "o.yaml")
    (tmp_path / "i.yaml").write_text(good.replace("m.png", "gone.pgm"))
    with pytest.raises(FloorplanError, match=r"i\.yaml: image file .*gone\.pgm' not found"):
        load_floorplan(tmp_path / "i.yaml")


def test_decisions_round_trip_and_errors(tmp_path):
    rows = [
        {
            "k": 1,
            "t": 3.5,
            "state": "DEFER",
            "anchor": None,
            "symmetry": None,
            "tau": None,
            "B1": 0.0,
            "B2": 0.0,
            "margin": 0.0,
        },
        {
            "k": 2,
            "t": 5.0,
            "state": "AMBIGUOUS",
            "anchor": None,
            "symmetry": "translation",
            "tau": [4.0, 0.0],
            "B1": 3.0,
            "B2": 3.0,
            "margin": 0.0,
        },
        {
            "k": 3,
            "t": 7.0,
            "state": "COMMIT",
            "anchor": {"x": 1.0, "y": 2.0, "yaw_deg": 90.0},
            "symmetry": None,
            "tau": None,
            "B1": 5.0,
            "B2": 1.0,
            "margin": 4.0,
        },
    ]
    path = write_decisions(tmp_path / "d.jsonl", rows)
    assert read_decisions(path) == rows
    bad = dict(rows[2], anchor=None)
    with pytest.raises(DataError, match="decision #1: a COMMIT needs an anchor"):
        write_decisions(tmp_path / "e.jsonl", [rows[0], bad])
    assert not (tmp_path / "e.jsonl").exists() and _leftovers(tmp_path, "e.jsonl") == []
    path.write_text(path.read_text().replace('"DEFER"', '"MAYBE"'))
    with pytest.raises(DataError, match=r"d\.jsonl:1: state='MAYBE'"):
        read_decisions(path)


def test_cli_floorplan_show_errors(tmp_path, capsys):
    from mfcl_jax.cli import main

    assert main(["floorplan", "show", str(tmp_path / "none.geojson")]) == 2
    err = capsys.readouterr().err
    assert "none.geojson: file not found" in err and "Traceback" not in err
    p = tmp_path / "plan.geojson"
    from mfcl_jax.floorplan import save_geojson

    save_geojson(_plan(), p)
    out = tmp_path / "plan.png"
    assert main(["floorplan", "show", str(p), "--out", str(out)]) == 0
    assert out.stat().st_size > 1000 and "2 rooms" in capsys.readouterr().out
