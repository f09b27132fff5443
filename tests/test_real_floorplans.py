"""The real floor plans and logs in ../shared/data load with plausible contents."""

from __future__ import annotations

import time

import numpy as np
import pytest

from mfcl_jax.floorplan import FloorplanError, load_floorplan, load_ifc, load_rosmap
from mfcl_jax.io import DataError, read_bag, read_carmen
from mfcl_jax.sources.data import data_dir

DATA = data_dir()
pytestmark = pytest.mark.skipif(
    not DATA.is_dir(), reason=f"real data folder {DATA} is absent (see shared/data/SOURCES.md)"
)
IFC = DATA / "ifc"
DUPLEX = IFC / "Duplex_A_20110907_Architecture.ifc"
OFFICE = IFC / "Office_A_20110811.ifc"
FZK = IFC / "AC20-FZK-Haus.ifc"


def _edges(fp) -> int:
    return int((fp.adjacency.sum() - len(fp.rooms)) // 2)


def test_duplex_without_a_storey_is_every_storey_side_by_side():
    fp = load_floorplan(DUPLEX)  # default: every storey with walls and spaces
    st = fp.storeys
    assert st.names == ("Level 1", "Level 2")  # T/FDN and Roof have no spaces / walls
    assert list(st.tile) == [0, 1]  # the two storeys differ: each has its place
    l1, l2 = load_ifc(DUPLEX, storey="Level 1"), load_ifc(DUPLEX, storey="Level 2")
    assert len(fp.rooms) == len(l1.rooms) + len(l2.rooms)
    assert all(n.startswith(("Level 1/", "Level 2/")) for n in fp.room_names)
    # a place on Level 2 maps back to Level 2's own frame
    c = np.asarray(l2.room_centroids[0])
    x, y = st.place[1][:2]  # the motion is a pure shift here (no turn)
    assert st.place[1][2] == 0
    assert st.tile_at(c[0] + x, c[1] + y) == 1
    assert np.allclose(st.to_storey(1, (c[0] + x, c[1] + y, 0.3))[:2], c)
    # what `mfcl` reads with --storey: still both storeys, the named one marked (by name or
    # by elevation)
    from mfcl_jax.floorplan.load import load_building

    assert load_building([DUPLEX], storey="Level 2").storeys.given == 1
    assert load_building([DUPLEX], storey=3.1).storeys.given == 1
    with pytest.raises(FloorplanError, match="unknown storey 'Basement'"):
        load_building([DUPLEX], storey="Basement")


def test_duplex_level1():
    fp = load_floorplan(DUPLEX, storey="Level 1")
    assert fp.name.endswith("Level 1")
    assert len(fp.rooms) == 10  # the 10 IfcSpace of Level 1
    assert 110 < fp.room_areas.sum() < 140
    names = " ".join(fp.room_names)
    for room in ("A102 Living Room", "B102 Living Room", "A101 Foyer", "B104 Bathroom 1"):
        assert room in names
    assert len(fp.wall_polygons) >= 20 and len(fp.doors) >= 6
    assert _edges(fp) >= 8
    # Units A and B are the same flat turned by 180 degrees: equal living-room areas.
    a, b = fp.room("A102 Living Room"), fp.room("B102 Living Room")
    assert abs(a.polygon.area - b.polygon.area) < 0.5
    x0, y0, x1, y1 = fp.bounds
    assert 8 < x1 - x0 < 10 and 17 < y1 - y0 < 19


def test_ifc_loads_are_identical_from_run_to_run():
    """The geometry iterator's threads finish in any order; rooms, doors and walls must not
    (random tours, room names and every benchmark number derived from them depend on it)."""
    import subprocess
    import sys

    code = (
        "from mfcl_jax.floorplan import load_ifc; import sys, hashlib; "
        f"fp = load_ifc({str(DUPLEX)!r}, storey='Level 1'); "
        "print([r.name for r in fp.rooms], [d.rooms for d in fp.doors], "
        "hashlib.sha1(b''.join(p.wkb for p in fp.wall_polygons)).hexdigest())"
    )
    outs = {
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                       env={**__import__("os").environ, "PYTHONHASHSEED": str(h)}).stdout
        for h in (1, 2, 3)
    }  # fmt: skip
    assert len(outs) == 1, outs


def test_duplex_storeys_and_errors():
    assert len(load_ifc(DUPLEX, storey="Level 2").rooms) >= 10
    assert load_ifc(DUPLEX, storey=3.1).name.endswith("Level 2")
    with pytest.raises(FloorplanError) as e:
        load_ifc(DUPLEX, storey="Basement")
    msg = str(e.value)
    assert DUPLEX.name in msg and "unknown storey 'Basement'" in msg and "'Level 2'" in msg
    with pytest.raises(FloorplanError, match=r"Duplex.*storey 'Roof'.*no wall crosses"):
        load_ifc(DUPLEX, storey="Roof")
    with pytest.raises(FloorplanError, match=r"Duplex.*storey 'T/FDN'.*no IfcSpace"):
        load_ifc(DUPLEX, storey="T/FDN")


def test_office_level1():
    t0 = time.perf_counter()
    fp = load_ifc(OFFICE)
    first = time.perf_counter() - t0
    assert first < 30.0, f"Office_A took {first:.1f} s"
    assert len(fp.rooms) == 60
    assert 1500 < fp.room_areas.sum() < 1850
    assert len(fp.wall_polygons) > 250 and len(fp.doors) >= 50
    assert _edges(fp) >= 50
    x0, y0, x1, y1 = fp.bounds
    assert 48 < x1 - x0 < 52 and 34 < y1 - y0 < 38
    t0 = time.perf_counter()
    assert load_ifc(OFFICE) is fp  # cached by path, mtime, storey and cut height
    assert time.perf_counter() - t0 < 0.1


def test_fzk_haus_ifc4():
    fp = load_ifc(FZK)
    assert len(fp.rooms) == 6
    assert 85 < fp.room_areas.sum() < 115
    flur = next(n for n in fp.room_names if "Flur" in n)
    # The hall joins every other room on the ground floor.
    assert fp.adjacency[fp.room_index(flur)].sum() - 1 >= 4


def test_willow_map_rooms():
    fp = load_floorplan(DATA / "maps" / "willow-full.yaml")
    assert len(fp.rooms) >= 8 and _edges(fp) >= 5
    assert fp.room_names[0] == "r00"
    # With the image's grey (206) read as unknown, the offices become separate rooms.
    fp = load_rosmap(DATA / "maps" / "willow-full.yaml", free_thresh=0.19)
    assert len(fp.rooms) >= 15 and _edges(fp) >= 15
    x0, y0, x1, y1 = fp.bounds
    assert 45 < x1 - x0 < 56 and 50 < y1 - y0 < 59


def test_intel_bag():
    t0 = time.perf_counter()
    bag = read_bag(DATA / "laser" / "intel.orig.bag")
    assert time.perf_counter() - t0 < 30
    assert len(bag) + bag.unpaired == 13631 and bag.unpaired <= 2
    assert len(bag.odom_times) == 26915
    assert np.all(np.diff(bag.times) >= 0)
    sizes = np.array([len(s) for s in bag.scans])
    assert np.median(sizes) > 100 and max(np.abs(s).max() for s in bag.scans[:50]) < 100
    assert np.all(np.isfinite(bag.odometry))


def test_bag_missing_topic():
    with pytest.raises(DataError) as e:
        read_bag(DATA / "laser" / "intel.orig.bag", scan_topic="/base_scan")
    msg = str(e.value)
    assert "intel.orig.bag" in msg and "no topic '/base_scan'" in msg
    assert "/scan (sensor_msgs/msg/LaserScan)" in msg and "/odom" in msg


def test_intel_carmen():
    log = read_carmen(DATA / "laser" / "intel-corrected.log.gz")
    assert len(log) == 910 and log.time_reversals == 4
    assert all(len(s) > 50 for s in log.scans[:20])
    # Corrected poses: consecutive scans seen from their poses overlap (walls coincide).
    from scipy.spatial import cKDTree

    def world(i):
        x, y, th = log.poses[i]
        c, s = np.cos(th), np.sin(th)
        p = log.scans[i]
        return np.stack([x + c * p[:, 0] - s * p[:, 1], y + s * p[:, 0] + c * p[:, 1]], -1)

    d, _ = cKDTree(world(100)).query(world(101))
    assert np.median(d) < 0.15
    with pytest.raises(DataError, match=r"intel-corrected\.log\.gz:\d+: timestamp"):
        read_carmen(DATA / "laser" / "intel-corrected.log.gz", strict_time=True)
