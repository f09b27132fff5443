"""Signals and batches: SIGTERM and SIGINT stop ``mfcl localize`` in every mode and what was
decided is written, atomically (one dataset: exit 130 / 143; ``--follow``: exit 0; several
datasets: the datasets decided so far); a batch reads every dataset before any work, names
every bad one at once, and with ``--keep-going`` decides the good ones and exits 2.

The signal cases start ``mfcl localize`` as a process, wait for its first status line and
signal it. A one-dataset run on this small walk would finish before a signal lands, so its
robot is made slow (half a second more per window). The batch stop and the refusals stub the
batch (``drive.batch.decide_batch``): they need the datasets read, not decided."""

from __future__ import annotations

import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from mfcl_jax.cli import main
from mfcl_jax.io import read_decisions
from mfcl_jax.robot.signals import Stopped, StopSignals

WAYPOINTS = np.array([[1.0, 4.2], [3.0, 1.8], [27.0, 1.8]])  # 109 scans, 8 windows of 6 m
MFCL = str(Path(sys.executable).parent / "mfcl")
SLOW = """
import signal, sys, time
from mfcl_jax.robot import localizer

signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal, even if ignored

run = localizer.Localizer.run


def slow(self, seq):  # a slow robot: each window takes half a second more
    for r in run(self, seq):
        yield r
        time.sleep(0.5)


localizer.Localizer.run = slow
from mfcl_jax.cli import main

sys.exit(main(sys.argv[1:]))
"""


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """A walk whose odometry restarts half-way (two segments)."""
    from mfcl_jax.sim import SimParams
    from mfcl_jax.sim.scenes import symmetric_bays
    from mfcl_jax.sources.simulated import simulate_dataset

    root = tmp_path_factory.mktemp("signals")
    p = SimParams(restart_at=0.5)
    return simulate_dataset(symmetric_bays().floorplan, WAYPOINTS, root / "walk", seed=1, params=p)


def _snapshot(folder):
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ------------------------------------------------------------------ a process, signalled
class _Lines:
    """The lines of a process's pipe, read by a thread (a queue to wait on)."""

    def __init__(self, pipe):
        self.lines, self._q = [], queue.Queue()
        threading.Thread(target=self._read, args=(pipe,), daemon=True).start()

    def _read(self, pipe):
        for line in pipe:
            self._q.put(line)
        self._q.put(None)

    def wait_for(self, prefix: str, timeout: float = 300.0) -> str:
        end = time.monotonic() + timeout
        while True:
            line = self._q.get(timeout=max(end - time.monotonic(), 0.01))
            if line is None:
                raise AssertionError(f"the process ended before a line {prefix!r}: {self.lines}")
            self.lines.append(line)
            if line.startswith(prefix):
                return line

    def rest(self) -> list[str]:
        while (line := self._q.get(timeout=60)) is not None:
            self.lines.append(line)
        return self.lines


def _start(argv):
    return subprocess.Popen(
        argv,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.parametrize(
    "sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)], ids=["SIGTERM", "SIGINT"]
)
def test_a_signal_stops_a_one_dataset_run_and_writes_what_was_decided(walk, tmp_path, sig,
                                                                      code):  # fmt: skip
    from mcap.reader import make_reader

    out, viz = tmp_path / "d.jsonl", tmp_path / "run.mcap"
    proc = _start([sys.executable, "-c", SLOW, "localize", str(walk), "--out", str(out),
                   "--viz", str(viz)])  # fmt: skip
    stdout, stderr = _Lines(proc.stdout), _Lines(proc.stderr)
    stdout.wait_for("k=")  # the first window is decided
    proc.send_signal(sig)
    assert proc.wait(timeout=120) == code
    shown = [ln for ln in stdout.rest() if ln.startswith("k=")]
    err = "".join(stderr.rest())
    decs = read_decisions(out)  # complete and valid
    assert 1 <= len(decs) == len(shown) < 8, (shown, err)
    assert [d["k"] for d in decs] == list(range(1, len(decs) + 1))
    name = "SIGTERM" if sig == signal.SIGTERM else "Ctrl-C"
    assert f"mfcl: stopped by {name}: {len(decs)} windows decided, written to {out}" in err
    assert f"exit status {code}" in err and "Traceback" not in err
    with viz.open("rb") as f:  # the viz file is written with the decisions
        kept = [m for _, c, m in make_reader(f).iter_messages() if c.topic == "/mfcl/decision"]
    assert len(kept) == len(decs)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left


def test_sigterm_stops_follow_and_writes_what_was_decided(walk, tmp_path):
    live = tmp_path / "live"
    shutil.copytree(walk, live)
    out = tmp_path / "f.jsonl"
    proc = _start([MFCL, "localize", "--follow", str(live), "--out", str(out),
                   "--idle-timeout", "300"])  # fmt: skip
    stdout, stderr = _Lines(proc.stdout), _Lines(proc.stderr)
    stderr.wait_for("k=")
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=120) == 0  # a live run is stopped by a signal: that is its end
    streamed = [ln for ln in stdout.rest() if ln.strip()]
    err = "".join(stderr.rest())
    decs = read_decisions(out)
    assert len(decs) == len(streamed) >= 1, err
    assert out.read_text() == "".join(streamed)  # every line streamed is in the file
    assert "stopped (SIGTERM): " in err and f"{len(decs)} windows" in err
    assert f"decisions: {out}" in err and "Traceback" not in err


def test_stop_signals_raise_once_and_never_while_writing():
    before = signal.getsignal(signal.SIGTERM)
    with StopSignals() as s:
        with pytest.raises(Stopped) as e:
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(200):
                time.sleep(0.01)
        assert e.value.signum == signal.SIGTERM and isinstance(e.value, KeyboardInterrupt)
        with s.writing():
            os.kill(os.getpid(), signal.SIGINT)  # remembered, not raised
            time.sleep(0.05)
        assert s.received == signal.SIGTERM
    assert signal.getsignal(signal.SIGTERM) is before


# ------------------------------------------------------------------ batches
def _fake_batch(stop_after=None):
    """A stand-in for ``decide_batch``: one DEFER window per recording; sends SIGTERM to
    this process after ``stop_after`` recordings."""
    from mfcl_jax.drive.batch import BatchResult

    calls = []

    def batch(fps, seqs, params=None, progress=None, budget=None, chunk=8, report=None):
        calls.append(len(seqs))
        for i, seq in enumerate(seqs):
            d = {"k": 1, "segment": 0, "t": float(seq.times[-1]), "state": "DEFER",
                 "anchor": None, "symmetry": None, "tau": None, "B1": 1, "B2": 0, "margin": 1,
                 "pose": None, "reason": "unsaturated", "alternatives": None}  # fmt: skip
            yield i, BatchResult([d], ["pts=1"])
            if stop_after is not None and i + 1 == stop_after:
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(5)

    return batch, calls


def test_sigterm_stops_a_batch_and_writes_the_datasets_decided(walk, tmp_path, monkeypatch,
                                                               capsys):  # fmt: skip
    from mfcl_jax.drive import batch as driver

    a, b = tmp_path / "a", tmp_path / "b"
    shutil.copytree(walk, a)
    shutil.copytree(walk, b)
    batch, _ = _fake_batch(stop_after=1)
    monkeypatch.setattr(driver, "decide_batch", batch)
    out = tmp_path / "out"
    assert main(["localize", str(a), str(b), "--out-dir", str(out)]) == 143
    cap = capsys.readouterr()
    assert sorted(p.name for p in out.iterdir()) == ["a.jsonl"]
    assert len(read_decisions(out / "a.jsonl")) == 1
    assert "b        -        -               not decided" in cap.out
    assert "mfcl: stopped by SIGTERM: 1 of 2 datasets decided and written, 1 not" in cap.err


def test_a_batch_names_every_bad_dataset_before_any_work(walk, tmp_path, monkeypatch, capsys):
    from mfcl_jax.drive import batch as driver

    good, broken, empty = tmp_path / "good", tmp_path / "broken", tmp_path / "empty"
    shutil.copytree(walk, good)
    shutil.copytree(walk, broken)
    (broken / "odometry.tum").write_text("0 1 2 3\n")
    empty.mkdir()
    missing = tmp_path / "missing"
    batch, calls = _fake_batch()
    monkeypatch.setattr(driver, "decide_batch", batch)
    before = _snapshot(tmp_path)
    out = tmp_path / "out"
    argv = ["localize", str(good), str(broken), str(empty), str(missing), "--out-dir", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("mfcl: error: 3 of 4 datasets cannot be used; nothing was decided")
    assert "--keep-going" in err and "Traceback" not in err
    for bad, words in ((broken, "8 columns"), (empty, "found none"), (missing, "not found")):
        (line,) = [ln for ln in err.splitlines() if str(bad) in ln]
        assert words in line, line
    assert calls == [] and not out.exists() and _snapshot(tmp_path) == before


def test_keep_going_decides_the_good_datasets_and_exits_2(walk, tmp_path, capsys):
    """The real batch: the good dataset decided (its records carry their segments, the split
    is noted), the bad ones named, the exit status 2."""
    good, broken = tmp_path / "good", tmp_path / "broken"
    shutil.copytree(walk, good)
    shutil.copytree(walk, broken)
    (broken / "odometry.tum").write_text("0 1 2 3\n")
    missing, out = tmp_path / "missing", tmp_path / "out"
    argv = ["localize", str(broken), str(good), str(missing), "--out-dir", str(out),
            "--keep-going"]  # fmt: skip
    assert main(argv) == 2
    cap = capsys.readouterr()
    assert sorted(p.name for p in out.iterdir()) == ["good.jsonl"]
    decs = read_decisions(out / "good.jsonl")
    assert [d["k"] for d in decs] == list(range(1, len(decs) + 1))
    segs = [d["segment"] for d in decs]
    assert segs == sorted(segs) and set(segs) == {0, 1}
    k1 = segs.index(1) + 1
    assert f"mfcl: {good}: odometry segment 1 starts at window {k1}: " in cap.err
    assert f"mfcl: error: {broken / 'odometry.tum'}:1: expected 8 columns" in cap.err
    assert f"mfcl: error: {missing}" in cap.err
    assert "mfcl: 2 of 3 datasets not decided (bad input, named above); exit status 2" in cap.err
    rows = {ln.split()[0]: ln.split()[1:] for ln in cap.out.splitlines()
            if ln.split()[:1] in (["good"], ["broken"], ["missing"])}  # fmt: skip
    assert rows["good"][0] == str(len(decs)) and rows["broken"] == ["-", "-", "bad", "input"]
    assert rows["missing"] == ["-", "-", "bad", "input"]


def test_keep_going_past_a_dataset_the_batch_cannot_decide(walk, tmp_path, monkeypatch, capsys):
    """A dataset that reads but that the batch refuses (a window over the capacity, say)
    stops the batch; with ``--keep-going`` the datasets left are decided one by one."""
    from mfcl_jax.drive import batch as driver
    from mfcl_jax.io import DataError

    a, b = tmp_path / "a", tmp_path / "b"
    shutil.copytree(walk, a)
    shutil.copytree(walk, b)
    fake, calls = _fake_batch()

    def batch(fps, seqs, *args, **kw):
        if len(seqs) > 1 or seqs[0].source == str(b):
            calls.append(-len(seqs))
            raise DataError(f"{seqs[-1].source}: a window over the capacity")
        yield from fake(fps, seqs, *args, **kw)

    monkeypatch.setattr(driver, "decide_batch", batch)
    out = tmp_path / "out"
    argv = ["localize", str(a), str(b), "--out-dir", str(out)]
    assert main(argv) == 2 and not out.exists()  # without --keep-going: an error, no output
    assert "a window over the capacity" in capsys.readouterr().err
    calls.clear()
    assert main([*argv, "--keep-going"]) == 2
    err = capsys.readouterr().err
    assert calls == [-2, 1, -1]  # the batch, then each dataset left alone
    assert sorted(p.name for p in out.iterdir()) == ["a.jsonl"]
    assert f"mfcl: error: {b}: a window over the capacity" in err
    assert "1 of 2 datasets not decided" in err
