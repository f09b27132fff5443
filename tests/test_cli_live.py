"""``mfcl localize --follow``: a writer thread copies a simulated dataset into a folder scan by
scan (odometry lines in pieces, one PCD empty then truncated before it is whole); the live run
streams the same decisions as a run on the finished folder. The follower's reading rules
(partial lines wait, bad lines and dead files are errors naming them) use a fake clock."""

from __future__ import annotations

import json
import shutil
import threading
import time

import numpy as np
import pytest

from mfcl_jax.cli import main
from mfcl_jax.io import DataError, read_decisions
from mfcl_jax.robot.live import Follower
from mfcl_jax.sim.scenes import symmetric_bays
from mfcl_jax.sources import write_dataset

# R1 -> door line -> R2 and on: 73 scans, 6 windows of 6 m.
WAYPOINTS = np.array([[1.0, 4.2], [3.0, 1.8], [18.0, 1.8]])
TRUNCATED = 7  # the scan written empty, then half, then whole


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from mfcl_jax.sources.simulated import simulate_dataset

    root = tmp_path_factory.mktemp("live")
    return simulate_dataset(symmetric_bays().floorplan, WAYPOINTS, root / "src", seed=1)


def _lines(src):
    return [ln for ln in (src / "odometry.tum").read_text().splitlines(keepends=True)
            if not ln.startswith("#")]  # fmt: skip


def _write(src, dst, delay=0.01):
    """Copies ``src`` into ``dst`` the way a recorder writes it (not atomically)."""
    with (dst / "odometry.tum").open("a") as odo:
        for i, line in enumerate(_lines(src)):
            t = line.split()[0]
            data = (src / "scans" / f"{t}.pcd").read_bytes()
            pcd = dst / "scans" / f"{t}.pcd"
            if i == TRUNCATED:
                pcd.write_bytes(b"")
                odo.write(line)
                odo.flush()
                time.sleep(0.3)
                pcd.write_bytes(data[: len(data) // 2])
                time.sleep(0.3)
                pcd.write_bytes(data)
            else:
                if i % 2:
                    pcd.write_bytes(data)
                odo.write(line[:9])  # half a line first: it must wait for the rest
                odo.flush()
                time.sleep(delay)
                odo.write(line[9:])
                odo.flush()
                if not i % 2:
                    pcd.write_bytes(data)
            time.sleep(delay)


def test_follow_streams_the_decisions_of_the_whole_run(dataset, tmp_path, capsys):
    live = tmp_path / "live"
    (live / "scans").mkdir(parents=True)
    shutil.copy(dataset / "floorplan.geojson", live)
    writer = threading.Thread(target=_write, args=(dataset, live), daemon=True)
    writer.start()
    out = tmp_path / "live.jsonl"
    argv = ["localize", "--follow", str(live), "--idle-timeout", "3", "--out", str(out)]
    assert main(argv) == 0
    writer.join()
    cap = capsys.readouterr()
    streamed = [json.loads(line) for line in cap.out.splitlines()]
    assert "stopped (no new data for 3 s): 73 scans (2-D), 6 windows" in cap.err
    assert "error" not in cap.err and "warning" not in cap.err
    assert read_decisions(out) == streamed
    ref = tmp_path / "ref.jsonl"
    assert main(["localize", str(dataset), "--out", str(ref), "--quiet"]) == 0
    whole = read_decisions(ref)
    assert len(streamed) == len(whole) == 6
    for a, b in zip(streamed, whole, strict=True):
        for key in ("k", "t", "state", "symmetry", "B1", "B2", "margin", "reason"):
            assert a[key] == b[key], key
        for key in ("anchor", "pose"):
            assert (a[key] is None) == (b[key] is None)
            if a[key] is not None:
                np.testing.assert_allclose(list(a[key].values()), list(b[key].values()), atol=1e-4)


def test_ctrl_c_stops_and_writes_what_it_has(dataset, tmp_path, monkeypatch, capsys):
    live = tmp_path / "live"
    live.mkdir()
    shutil.copy(dataset / "floorplan.geojson", live)

    def interrupted(self):
        raise KeyboardInterrupt
        yield

    monkeypatch.setattr(Follower, "prefixes", interrupted)
    out = tmp_path / "o.jsonl"
    assert main(["localize", "--follow", str(live), "--out", str(out)]) == 0
    assert "stopped (Ctrl-C): 0 scans, 0 windows" in capsys.readouterr().err
    assert out.read_text() == ""


def test_follow_bad_inputs(dataset, tmp_path, capsys):
    def fails(argv, *words):
        assert main([str(a) for a in argv]) == 2
        err = capsys.readouterr().err
        assert err.startswith("mfcl: error:") and err.count("\n") == 1
        for w in words:
            assert str(w) in err, err

    empty = tmp_path / "empty"
    empty.mkdir()
    out = tmp_path / "o.jsonl"
    fails(["localize", "--follow", empty, "--out", out], empty, "needs the floor plan first")
    fails(["localize", "--follow", tmp_path / "none"], "none: dataset folder not found")
    fails(["localize", "--follow", dataset, dataset], "reads that folder only")
    fails(["localize", "--follow", dataset, "--idle-timeout", "0"], "--idle-timeout", "got 0")
    fails(["localize", "--follow", dataset, "--out-dir", tmp_path], "not --out-dir")
    fails(["localize", "--follow", dataset, "--out", dataset / "odometry.tum"], "odometry.tum")
    assert not out.exists()


# ------------------------------------------------------------------ the follower's rules
class _Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now

    def sleep(self, s):
        self.now += s


def _folder(tmp_path, n=3):
    ds = write_dataset(tmp_path / "ds", symmetric_bays().floorplan, np.arange(n, dtype=float),
                       [np.ones((4, 2)) * (i + 1) for i in range(n)], np.zeros((n, 3)))  # fmt: skip
    return ds


def test_partial_lines_wait_and_bad_lines_are_named(tmp_path):
    ds = _folder(tmp_path)
    lines = (ds / "odometry.tum").read_text().splitlines(keepends=True)
    clock = _Clock()
    f = Follower(ds, idle_timeout=1.0, clock=clock, sleep=clock.sleep)
    (ds / "odometry.tum").write_text(lines[0] + lines[1] + lines[2][:5])
    seqs = f.prefixes()
    assert len(next(seqs)) == 1 and f.n_odometry == 1  # (line 1 is the header)
    with (ds / "odometry.tum").open("a") as o:
        o.write(lines[2][5:] + "9 x 0 0 0 0 0 1\n")
    with pytest.raises(DataError, match=r"odometry\.tum:4: not a number in '9 x 0 0 0 0 0 1'"):
        next(seqs)


def test_an_unreadable_scan_is_retried_then_named(tmp_path):
    ds = _folder(tmp_path)
    scans = sorted((ds / "scans").iterdir(), key=lambda p: float(p.stem))
    whole = scans[1].read_bytes()
    scans[1].write_bytes(whole[:-7])
    clock = _Clock()
    f = Follower(ds, idle_timeout=30.0, settle=5.0, clock=clock, sleep=clock.sleep)
    seqs = f.prefixes()
    assert len(next(seqs)) == 1
    t0 = clock.now
    with pytest.raises(DataError, match=r"1\.pcd: binary data truncated .*\(unchanged for 5 s"):
        next(seqs)
    assert clock.now - t0 >= 5.0
    scans[1].write_bytes(b"")  # empty, as a recorder leaves it: retried until idle, then
    g = Follower(ds, idle_timeout=2.0, clock=clock, sleep=clock.sleep)  # named (issue 52)
    got = []
    with pytest.raises(DataError, match=r"1\.pcd: .*\(nothing new for 2 s while 1 later scans"):
        for seq in g.prefixes():
            got.append(len(seq))
    assert got == [1]
    assert "first " in g.pending()[0] and "1.pcd (unreadable" in g.pending()[0]
    scans[1].write_bytes(whole)
    assert [len(s) for s in g.prefixes()] == [3] and g.pending() == []


def test_odometry_at_its_own_rate_is_interpolated_at_each_scan_as_it_arrives(tmp_path):
    """100 Hz odometry on stamps unlike the scans' (issue 29 item 1, in --follow too): a scan
    joins once the odometry's complete lines pass its stamp, with the pose a finished folder
    gives it; a scan stamped before the odometry's first line is left out and counted."""
    from mfcl_jax.sources import from_dataset, load_dataset

    st = np.array([0.5, 1.0037, 1.5037, 2.0037])  # the first before the odometry starts
    to = 1.0 + 0.01 * np.arange(120)  # 100 Hz from t = 1.0 to 2.19
    odo = np.stack([0.2 * (to - 1), 0.1 * np.sin(to), 0.3 * to], -1)
    ds = write_dataset(tmp_path / "ds", symmetric_bays().floorplan, st,
                       [np.ones((4, 2)) * (i + 1) for i in range(len(st))], odo,
                       odom_times=to)  # fmt: skip
    lines = (ds / "odometry.tum").read_text().splitlines(keepends=True)
    (ds / "odometry.tum").write_text("".join(lines[:60]))  # odometry up to t = 1.58
    clock = _Clock()
    f = Follower(ds, idle_timeout=1.0, clock=clock, sleep=clock.sleep)
    seqs = f.prefixes()
    first = next(seqs)
    assert len(first) == 2  # 1.0037 and 1.5037; 2.0037 waits for the odometry
    with (ds / "odometry.tum").open("a") as o:
        o.write("".join(lines[60:]))
    whole = next(seqs)
    assert list(seqs) == []
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the finished folder warns about the early scan
        ref = from_dataset(load_dataset(ds))
    np.testing.assert_array_equal(whole.times, ref.times)
    np.testing.assert_allclose(whole.odometry, ref.odometry, atol=1e-9)
    assert any("1 scans stamped before the odometry's first line" in p for p in f.pending())
