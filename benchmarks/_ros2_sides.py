"""The two observers of ``benchmarks/ros2_node.py``'s replays: nav2's side of the wire (a
reader of ``/mfcl/status`` and ``/initialpose`` over real DDS, stamping each arrival) and the
node's resident memory sampled from ``/proc``."""

from __future__ import annotations

import json
import pathlib
import threading
import time


class Nav2Side:
    """Reads ``/mfcl/status`` and ``/initialpose``, stamping each arrival (monotonic s)."""

    def __init__(self):
        from mfcl_jax.ros2 import messages as M
        from mfcl_jax.ros2.dds import LATCHED, RELIABLE, Bus, take

        bus = Bus()
        self._status = bus.reader("/mfcl/status", M.String, RELIABLE)
        self._pose = bus.reader("/initialpose", M.PoseWithCovarianceStamped, LATCHED)
        self._wait = bus.waiter([self._status, self._pose])
        self.status, self.poses, self._stop = [], [], False

        def loop():
            while not self._stop:
                self._wait(0.05)
                now = time.monotonic()
                self.status += [(now, json.loads(s.data)) for s in take(self._status)]
                self.poses += [(now, p) for p in take(self._pose)]

        self._thread = threading.Thread(target=loop, daemon=True)
        self._thread.start()

    def windows(self):
        return [(w, s) for w, s in self.status if "event" not in s]

    def close(self):
        self._stop = True
        self._thread.join()


class Memory:
    """The resident memory of a process every ``every`` seconds (MiB, from /proc)."""

    def __init__(self, pid: int, every: float = 5.0):
        self.rows, self._stop = [], False
        t0 = time.monotonic()

        def loop():
            while not self._stop:
                try:
                    text = pathlib.Path(f"/proc/{pid}/status").read_text()
                except OSError:
                    return
                rss = [x for x in text.splitlines() if x.startswith("VmRSS")]
                if not rss:  # the process has ended
                    return
                kb = int(rss[0].split()[1])
                self.rows.append((time.monotonic() - t0, kb / 1024))
                time.sleep(every)

        self._thread = threading.Thread(target=loop, daemon=True)
        self._thread.start()

    def close(self):
        self._stop = True
