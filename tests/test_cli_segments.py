"""Odometry segments in the record: every decisions line carries its segment and the window's
index over the whole recording; ``mfcl localize`` says on stderr where and why a run was split
(the input odometry's step test, or the LiDAR odometry's jump test); ``mfcl evaluate`` takes
the lines in time order, reports each segment, prints its tolerances and exits
``EXIT_FALSE_COMMIT`` on a false commit (``--exit-zero``: 0).

One simulated walk (109 scans, 8 windows of 6 m) is the source of two datasets: the odometry
re-zeroed half-way (a restart: a step no robot makes) and the odometry shifted 1.2 m half-way
(a jump the step test lets pass; the scans do not fit it). The evaluate cases use small
hand-written TUM files (no localization)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from mfcl_jax import se2
from mfcl_jax.cli import main
from mfcl_jax.cli.evaluate import EXIT_FALSE_COMMIT
from mfcl_jax.io import DataError, read_decisions, read_tum, write_decisions, write_tum

WAYPOINTS = np.array([[1.0, 4.2], [3.0, 1.8], [27.0, 1.8]])
STEP = "the input odometry's step test"
LIDAR = "the LiDAR odometry's jump test"


def _stamps(folder):
    lines = (folder / "odometry.tum").read_text().splitlines()
    return [ln.split()[0] for ln in lines if ln.strip() and not ln.startswith("#")]


def _rewrite(src, dst, change):
    """A copy of dataset ``src`` whose odometry is ``change(poses)``; returns the index of
    the first changed pose."""
    shutil.copytree(src, dst)
    t, odo = read_tum(src / "odometry.tum")
    r = len(odo) // 2
    write_tum(dst / "odometry.tum", t, change(odo.copy(), r), _stamps(src))
    return r


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    from mfcl_jax.sim.scenes import symmetric_bays
    from mfcl_jax.sources.simulated import simulate_dataset

    root = tmp_path_factory.mktemp("segments")
    walk = simulate_dataset(symmetric_bays().floorplan, WAYPOINTS, root / "walk", seed=1)

    def restart(odo, r):  # the odometry starts again from the identity at scan r
        odo[r:] = np.asarray(se2.between(odo[r], odo[r:]), np.float64)
        return odo

    def shift(odo, r):  # 1.2 m sideways at scan r: inside what a robot may move in 0.5 s
        odo[r:, 1] += 1.2
        return odo

    r = _rewrite(walk, root / "restart", restart)
    assert _rewrite(walk, root / "shifted", shift) == r
    return root, r


def _segment_runs(decs):
    """The segments in order of the lines, and the k where each starts."""
    starts = [(d["segment"], d["k"]) for i, d in enumerate(decs)
              if i == 0 or d["segment"] != decs[i - 1]["segment"]]  # fmt: skip
    return starts


# ------------------------------------------------------------------ mfcl localize
@pytest.mark.parametrize("name, why", [("restart", STEP), ("shifted", LIDAR)])
def test_a_split_run_carries_its_segments_and_says_where_and_why(data, tmp_path, capsys, name,
                                                                 why):  # fmt: skip
    root, r = data
    out = tmp_path / "d.jsonl"
    assert main(["localize", str(root / name), "--out", str(out)]) == 0
    cap = capsys.readouterr()
    decs = read_decisions(out)
    lines = out.read_text().splitlines()
    # Every line carries its segment, right after k; k counts over the whole recording.
    assert all(list(json.loads(ln))[:3] == ["k", "segment", "t"] for ln in lines)
    assert [d["k"] for d in decs] == list(range(1, len(decs) + 1))
    starts = _segment_runs(decs)
    assert [s for s, _ in starts] == [0, 1], starts
    k1 = starts[1][1]
    assert 1 < k1 < len(decs)
    # Where and why, on stderr: the window, the time and scan of the jump, the test.
    scan_t = float(_stamps(root / name)[r])
    note = [ln for ln in cap.err.splitlines() if "odometry segment" in ln]
    assert len(note) == 1, cap.err
    assert f"odometry segment 1 starts at window {k1}: " in note[0]
    assert f"at t={scan_t:.2f} s (scan {r}) found by {why}" in note[0]
    assert "the decision layer starts over" in note[0].lower()
    # The status lines show the segment after the jump; the summary counts the segments.
    status = [ln for ln in cap.out.splitlines() if ln.startswith("k=")]
    assert ("segment=1" in status[k1 - 1]) and ("segment=" not in status[k1 - 2])
    assert f"{len(decs)} windows in 2 odometry segments" in cap.out


def test_the_split_note_names_segments_without_a_window():
    """A pure check of the note (no localization): two input jumps between two windows, the
    first segment too short for a window; and a jump only the LiDAR test found, placed
    between two windows' times when the window's first scan is not known (a batch)."""
    from mfcl_jax.cli.segments import Splits
    from mfcl_jax.sources.sequence import ScanSequence
    from mfcl_jax.windows import WindowParams

    t = np.arange(60) * 0.5
    odo = np.zeros((60, 3))
    odo[:, 0] = 0.5 * np.arange(60)  # 1 m/s along x: every scan a keyframe
    odo[30:, 0] += 20.0  # a jump at scan 30
    odo[33:, 0] -= 40.0  # and at scan 33
    seq = ScanSequence(t, [np.zeros((1, 2))] * 60, odo, "walk")
    s = Splits(WindowParams(), "walk")
    assert s.note(seq, 1, 0, t[20], first=8, last=20) is None
    note = s.note(lambda: seq, 2, 2, t[45], first=33, last=45)
    assert "odometry segment 2 starts at window 2" in note
    assert f"t=15.00 s (scan 30) found by {STEP}: the input odometry moves 20.50 m" in note
    assert f"t=16.50 s (scan 33) found by {STEP}" in note
    assert "1 segment in between held no complete window" in note
    b = Splits(WindowParams(), "walk")
    assert b.note(seq, 1, 0, t[10]) is None
    note = b.note(seq, 2, 1, t[25])  # no input jump between scans 10 and 25
    assert f"1 jump between t=5.00 s and t=12.50 s found by {LIDAR}" in note


# ------------------------------------------------------------------ the decisions file
def _line(k, t, state="DEFER", anchor=None, **kw):
    d = {"k": k, "t": float(t), "state": state, "anchor": anchor, "symmetry": None,
         "tau": None, "B1": 1, "B2": 0, "margin": 1}  # fmt: skip
    return d | kw


@pytest.mark.parametrize("bad", [-1, 1.5, "1", True, None])
def test_a_bad_segment_is_named(tmp_path, bad):
    path = tmp_path / "d.jsonl"
    path.write_text(json.dumps(_line(1, 1.0, segment=0)) + "\n"
                    + json.dumps(_line(2, 2.0, segment=bad)) + "\n")  # fmt: skip
    with pytest.raises(DataError, match=r"d\.jsonl:2: segment=.*expected an integer >= 0"):
        read_decisions(path)
    rows = [_line(1, 1.0, segment=3, pose=None)]
    assert read_decisions(write_decisions(tmp_path / "ok.jsonl", rows)) == rows
    assert list(json.loads((tmp_path / "ok.jsonl").read_text()))[:3] == ["k", "segment", "t"]


# ------------------------------------------------------------------ mfcl evaluate
@pytest.fixture
def truth(tmp_path):
    """A dataset folder for evaluate: odometry = ground truth (the identity anchor is right),
    1 m/s along x for 60 s."""
    ds = tmp_path / "ds"
    ds.mkdir()
    t = np.arange(0.0, 60.5, 0.5)
    poses = np.stack([t, np.zeros_like(t), np.zeros_like(t)], 1)
    write_tum(ds / "odometry.tum", t, poses)
    write_tum(ds / "groundtruth.tum", t, poses)
    return ds


RIGHT = {"x": 0.0, "y": 0.0, "yaw_deg": 0.0}
WRONG = {"x": 4.0, "y": 0.0, "yaw_deg": 0.0}


def _evaluate(ds, rows, capsys, *flags, name="d.jsonl"):
    path = ds.parent / name
    path.write_text("".join(json.dumps(d) + "\n" for d in rows))
    code = main(["evaluate", str(ds), "--decisions", str(path), *flags])
    return code, capsys.readouterr().out


def _table(out, head):
    """The rows of the table whose header starts with ``head`` (cells stripped)."""
    lines = out.splitlines()
    i = next(i for i, ln in enumerate(lines)
             if ln.startswith("|") and ln.strip("|").split("|")[0].strip() == head)  # fmt: skip
    cols = [c.strip() for c in lines[i].strip("|").split("|")]
    rows = []
    for ln in lines[i + 2 :]:
        if not ln.startswith("|"):
            break
        rows.append(dict(zip(cols, (c.strip() for c in ln.strip("|").split("|")), strict=True)))
    return rows


def test_evaluate_takes_the_lines_in_time_order_not_by_k(truth, capsys):
    """A file of the old numbering (k starting again at 1 after a jump, no segment): sorted
    by k, the final state was COMMIT though the last line is DEFER, and the first commit was
    segment 1's (t=50) instead of segment 0's (t=15)."""
    rows = [_line(1, 5), _line(2, 10), _line(3, 15, "COMMIT", RIGHT), _line(4, 20, "COMMIT", RIGHT),
            _line(1, 40), _line(2, 50, "COMMIT", RIGHT), _line(3, 55)]  # fmt: skip
    code, out = _evaluate(truth, rows, capsys)
    assert code == 0
    (run,) = _table(out, "windows")
    got = (run["final state"], run["first commit k"], run["t"], run["commits correct"])
    assert got == ("DEFER", "3", "15.00", "3/3")
    assert run["segments"] == "2"
    assert "no segment field" in out  # the segments were inferred where k starts again
    seg = _table(out, "segment")
    assert [(s["segment"], s["k"], s["first commit k"], s["final state"]) for s in seg] == [
        ("0", "1-4", "3", "COMMIT"),
        ("1", "1-3", "2", "DEFER"),
    ]
    # Lines out of time order in a file with segments: the same report.
    new = [d | {"segment": int(i >= 4)} for i, d in enumerate(rows)]
    code, again = _evaluate(truth, new[4:] + new[:4], capsys, name="e.jsonl")
    assert code == 0 and _table(again, "windows") == [run] and _table(again, "segment") == seg
    assert "no segment field" not in again


def test_evaluate_prints_its_tolerances_and_fails_on_a_false_commit(truth, capsys):
    ok = [_line(1, 10, segment=0), _line(2, 15, "COMMIT", RIGHT, segment=0)]
    code, out = _evaluate(truth, ok, capsys, "--windows")
    assert code == 0
    assert "within 1.00 m and 5.0 deg of groundtruth.tum" in out
    assert "verdict: no false commit (1/1 COMMIT windows correct)" in out
    win = _table(out, "k")
    assert [(w["state"], w["correct"], w["err_xy"]) for w in win] == [
        ("DEFER", "-", "-"),  # an uncommitted window is not judged
        ("COMMIT", "yes", "0.00"),
    ]
    # A later commit that is wrong (a second segment): exit EXIT_FALSE_COMMIT, and it says.
    bad = ok + [_line(1, 40, segment=1), _line(2, 50, "COMMIT", WRONG, segment=1)]
    code, out = _evaluate(truth, bad, capsys)
    assert code == EXIT_FALSE_COMMIT == 3
    assert "verdict: FALSE COMMIT: 1 of 2 COMMIT windows are wrong, the first at k=2 " in out
    assert "(t=50.00 s, segment 1): 4.00 m" in out and "exit status 3" in out
    seg = _table(out, "segment")
    assert [s["verdict"] for s in seg] == ["correct", "FALSE"]
    code, out = _evaluate(truth, bad, capsys, "--exit-zero")
    assert code == 0 and "FALSE COMMIT" in out and "(--exit-zero)" in out


def test_help_documents_the_exit_statuses(capsys):
    for argv in (["evaluate", "--help"], ["localize", "--help"]):
        with pytest.raises(SystemExit):
            main(argv)
    out = capsys.readouterr().out
    assert "--exit-zero" in out and f"{EXIT_FALSE_COMMIT}    a false commit" in out
    assert "within 1 m and 5 deg" in out
    for words in ("--keep-going", "130  one dataset", "143  the same, stopped by SIGTERM",
                  "segment is\n  its odometry segment"):  # fmt: skip
        assert words in out
    from mfcl_jax.score import CORRECT_XY, CORRECT_YAW_DEG

    assert (CORRECT_XY, CORRECT_YAW_DEG) == (1.0, 5.0)  # the help's numbers
