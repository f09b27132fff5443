"""Failures a user met that went unnamed, each with the behaviour that replaced it: a bad
input is named (file, field, value) and counted, what was decided is written whatever stops
a run, a stop signal is never lost, and a file that is not what it claims is refused.

1. a dataset lacking ``odometry.tum`` in a folder of datasets is named and counted;
2. ``--follow`` stopped by an unreadable scan writes what it decided and says why (exit 2);
3. a stop signal whose exception Python drops (raised inside a garbage-collector callback,
   as during JAX's compilation) still stops the run; a signal during shutdown ends it with
   128 + signal, no traceback;
4. ``evaluate`` judges the ``pose`` a robot reads, and refuses repeated ``k`` and time going
   back within a segment;
5. ``simulate`` refuses a walk outside the building, and ``--overwrite`` of a folder that is
   not a dataset;
6. a recording whose every scan is empty, and a truncated IFC file, are named for what they
   are."""

from __future__ import annotations

import gc
import json
import shutil
import signal
import subprocess
import sys

import numpy as np
import pytest

from mfcl_jax.cli import main
from mfcl_jax.floorplan import save_geojson
from mfcl_jax.io import read_decisions, read_tum
from mfcl_jax.io.pcd import write_pcd
from mfcl_jax.robot.signals import Stopped, StopSignals
from mfcl_jax.se2 import compose_host, inverse_host
from mfcl_jax.sim.scenes import symmetric_bays

WAYPOINTS = [(1.0, 4.2), (3.0, 1.8), (27.0, 1.8)]  # test_cli's walk: 109 scans, 11 windows


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    root = tmp_path_factory.mktemp("named")
    plan = root / "bays.geojson"
    save_geojson(symmetric_bays().floorplan, plan)
    wp = root / "wp.csv"
    wp.write_text("\n".join(f"{x},{y}" for x, y in WAYPOINTS) + "\n")
    ds = root / "ds"
    argv = ["simulate", "--floorplan", str(plan), "--trajectory", str(wp), "--out", str(ds)]
    assert main([*argv, "--seed", "3"]) == 0
    return root, plan, ds


def _fails(argv, capsys, *names, code=2):
    assert main(argv) == code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    for n in names:
        assert str(n) in err, err
    return err


# 1 ---------------------------------------------------------------- a folder of datasets
def test_a_dataset_without_odometry_in_a_folder_is_named_and_counted(sim, tmp_path, capsys):
    _, _, ds = sim
    root = tmp_path / "many"
    shutil.copytree(ds, root / "a")
    shutil.copytree(ds, root / "b")
    (root / "b" / "odometry.tum").unlink()
    out = tmp_path / "out"
    err = _fails(["localize", str(root), "--out-dir", str(out)], capsys,
                 root / "b" / "odometry.tum", "1 of 2 datasets")  # fmt: skip
    assert "nothing was decided" in err and not out.exists()


# 2 ---------------------------------------------------------------- --follow, a bad scan
def test_follow_stopped_by_an_unreadable_scan_writes_what_it_decided(sim, tmp_path, capsys):
    _, _, ds = sim
    live = tmp_path / "live"
    shutil.copytree(ds, live)
    scans = sorted((live / "scans").iterdir(), key=lambda p: float(p.stem))
    bad = scans[80]
    bad.write_bytes(b"not a point cloud\n")  # unchanged, with later scans waiting behind it
    out = tmp_path / "follow.jsonl"
    argv = ["localize", "--follow", str(live), "--out", str(out), "--idle-timeout", "1",
            "--quiet"]  # fmt: skip
    # named at once if the scan stayed unreadable while later ones arrived, else at the idle
    # stop (1 s, under the 5 s a scan being written is given): either way, exit 2
    err = _fails(argv, capsys, f"error: {bad}: header has no DATA line", "exit status 2")
    decided = read_decisions(out)
    assert decided and [d["k"] for d in decided] == list(range(1, len(decided) + 1))
    assert max(d["t"] for d in decided) < float(bad.stem)
    assert f"decisions: {out}" in err


# 3 ---------------------------------------------------------------- a stop never lost
def _stop_inside_gc():
    """Raises SIGINT inside a garbage-collector callback: the handler runs there, and Python
    drops what it raises (``sys.unraisablehook``), as it does in JAX's ``_xla_gc_callback``."""

    def callback(phase, info):
        if phase == "start":
            gc.callbacks.remove(callback)
            signal.raise_signal(signal.SIGINT)
            for _ in range(100):  # the pending handler runs on this bytecode
                pass

    gc.callbacks.append(callback)
    gc.collect()


@pytest.fixture
def terminal_sigint():
    """SIGINT handled as in a terminal, even where the suite was started with it ignored (a
    background job of a script: the stop layer rightly leaves an ignored signal alone)."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)


def _terminal_sigint():  # the same for a child process (``preexec_fn``)
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_a_stop_dropped_by_python_still_stops_the_run(capfd, terminal_sigint):
    from mfcl_jax.robot.progress import Progress

    reached = []

    def work():
        _stop_inside_gc()
        reached.append("after the lost stop")
        with Progress(False).stage("the next stage"):  # a checkpoint: the stop is raised
            reached.append("inside the next stage")

    with StopSignals() as signals:
        stop = signals.run(work)
    assert signals.dropped == 1  # Python did drop it ...
    assert isinstance(stop, Stopped) and stop.signum == signal.SIGINT  # ... and it stopped
    assert reached == ["after the lost stop"]

    with StopSignals() as signals:  # no checkpoint after it: the run ends, reported stopped
        stop = signals.run(_stop_inside_gc)
    assert signals.dropped == 1 and isinstance(stop, Stopped)
    assert "Exception ignored" not in capfd.readouterr().err  # not shown as an error


def test_a_stop_never_splits_an_atomic_step():
    """A window's record is kept and its line shown, or neither: a signal during the step is
    raised right after it (``signals.atomic``)."""
    import os
    import time

    from mfcl_jax.robot.signals import atomic

    done = []

    def work():
        with atomic():
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)  # the handler runs here: remembered, not raised
            done.append("the whole step")
        done.append("the next step")

    with StopSignals() as signals:
        stop = signals.run(work)
    assert done == ["the whole step"] and stop.signum == signal.SIGTERM


def test_a_signal_during_shutdown_exits_with_its_status_and_no_traceback():
    code = (
        "import atexit, os, signal, time\n"
        "from mfcl_jax.robot.signals import exit_on_signal\n"
        "atexit.register(lambda: (os.kill(os.getpid(), signal.SIGINT), time.sleep(5)))\n"
        "exit_on_signal()\n"
        "print('outputs written', flush=True)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                       preexec_fn=_terminal_sigint)  # fmt: skip
    assert r.returncode == 130 and "outputs written" in r.stdout
    assert "Traceback" not in r.stderr, r.stderr


# 4 ---------------------------------------------------------------- evaluate
def _line(k, t, anchor, pose, segment=0):
    a = {"x": anchor[0], "y": anchor[1], "yaw_deg": float(np.rad2deg(anchor[2]))}
    p = {"x": pose[0], "y": pose[1], "yaw_deg": float(np.rad2deg(pose[2]))}
    return json.dumps({"k": k, "segment": segment, "t": t, "state": "COMMIT", "anchor": a,
                       "symmetry": None, "tau": None, "B1": 5, "B2": 1, "margin": 4,
                       "pose": p, "reason": "", "alternatives": None})  # fmt: skip


def test_evaluate_judges_the_pose_and_refuses_disorder(sim, tmp_path, capsys):
    _, _, ds = sim
    ot, odo = read_tum(ds / "odometry.tum")
    gt_t, gt = read_tum(ds / "groundtruth.tum")
    i, j = 60, 90
    A = [compose_host(gt[n], inverse_host(odo[n])) for n in (i, j)]  # the true anchors
    t = [float(ot[i]), float(ot[j])]
    dec = tmp_path / "dec.jsonl"

    def evaluate(*lines, code):
        dec.write_text("\n".join(lines) + "\n")
        assert main(["evaluate", str(ds), "--decisions", str(dec)]) == code
        got = capsys.readouterr()
        assert "Traceback" not in got.err
        return got.out, got.err

    right = [_line(1, t[0], A[0], gt[i]), _line(2, t[1], A[1], gt[j])]
    out, _ = evaluate(*right, code=0)
    assert "2/2 COMMIT windows correct" in out
    moved = gt[j] + np.array([3.0, 0.0, 0.0])  # the anchor right, the pose 3 m off
    out, _ = evaluate(right[0], _line(2, t[1], A[1], moved), code=3)
    assert "FALSE COMMIT: 1 of 2" in out and "3.00 m" in out
    _, err = evaluate(right[0], _line(1, t[1], A[1], gt[j]), code=2)
    assert f"{dec}:2: k=1 repeats line 1" in err
    swapped = (right[1].replace('"k": 2', '"k": 1'), right[0].replace('"k": 1', '"k": 2'))
    _, err = evaluate(*swapped, code=2)
    assert f"{dec}:2: t={t[0]} goes back from t={t[1]}" in err
    # a new segment may start earlier in time (the odometry restarted)
    evaluate(*right, _line(3, t[0], A[0], gt[i], segment=1), code=0)


# 5 ---------------------------------------------------------------- simulate
def test_simulate_refuses_a_walk_outside_and_overwriting_a_non_dataset(sim, tmp_path, capsys):
    _, plan, _ = sim
    outside = tmp_path / "outside.csv"
    outside.write_text("-20,-20\n-10,-20\n")
    _fails(["simulate", "--floorplan", str(plan), "--trajectory", str(outside), "--out",
            str(tmp_path / "o")], capsys, outside, "waypoint 1 (-20.00, -20.00) lies outside",
           "2 of 2 waypoints outside")  # fmt: skip
    assert not (tmp_path / "o").exists()
    mine = tmp_path / "my_notes"
    mine.mkdir()
    (mine / "thesis.tex").write_text("months of work\n")
    wp = tmp_path / "wp.csv"
    wp.write_text("\n".join(f"{x},{y}" for x, y in WAYPOINTS) + "\n")
    _fails(["simulate", "--floorplan", str(plan), "--trajectory", str(wp), "--out", str(mine),
            "--overwrite"], capsys, mine, "no odometry.tum", "left as it is")  # fmt: skip
    assert (mine / "thesis.tex").read_text() == "months of work\n"


# 6 ---------------------------------------------------------------- empty scans, a cut IFC
def test_all_empty_scans_and_a_truncated_ifc_are_named(sim, tmp_path, capsys):
    _, _, ds = sim
    empty = tmp_path / "empty"
    shutil.copytree(ds, empty)
    scans = list((empty / "scans").iterdir())
    for p in scans:
        write_pcd(p, np.zeros((0, 3)))
    out = tmp_path / "dec.jsonl"
    _fails(["localize", str(empty), "--out", str(out)], capsys, empty,
           f"every one of its {len(scans)} scans is empty")  # fmt: skip
    assert not out.exists()
    cut = tmp_path / "building.ifc"
    head = "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nENDSEC;\nDATA;\n"
    cut.write_text(head + "#1=IFCPROJECT('0YvctVUKr0kugbFTf53O9L',$,'P',$,$,$,$,$,$);\n#2=IFCW")
    _fails(["localize", str(ds), "--floorplan", str(cut), "--out", str(out)], capsys, cut,
           "truncated", "END-ISO-10303-21;")  # fmt: skip
    assert not out.exists()
