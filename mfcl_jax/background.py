"""Work started in a background thread and waited for where its result is needed.

Compilation is the longest wait of a cold start and needs only the inputs' shapes, so the
robot compiles its step while the LiDAR odometry runs, and the study compiles its decision
programs while the front-end registers (``Pending``). XLA compiles without holding Python's
lock, so on two cores the compiler and the work overlap.
"""

from __future__ import annotations

import threading

__all__ = ["Pending", "COMPILER"]

# one background compilation at a time: the foreground keeps a core
COMPILER = threading.Lock()


class Pending:
    """``make()`` run in a background thread; ``result()`` waits for it and returns it, or
    raises what it raised. Not a daemon: a process that ends before asking waits for the
    thread rather than tear the runtime down under a compiler."""

    def __init__(self, make, name: str = "mfcl-background"):
        self._out, self._err = None, None
        self._thread = threading.Thread(target=self._run, args=(make,), name=name)
        self._thread.start()

    def _run(self, make):
        try:
            with COMPILER:
                self._out = make()
        except BaseException as e:  # noqa: BLE001 - raised again in the caller's thread
            self._err = e

    def result(self):
        self._thread.join()
        if self._err is not None:
            raise self._err
        return self._out
