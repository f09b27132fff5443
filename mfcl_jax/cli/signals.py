"""Ctrl-C (SIGINT) and SIGTERM (``systemd stop``, ``docker stop``, ``timeout``) stop a
``mfcl localize`` run the same way, in every mode: the work stops, and what was decided so far
is written (atomically, like a finished run's output).

``StopSignals`` turns either signal into ``Stopped`` (a ``KeyboardInterrupt``) raised where
the run is; once the run writes its outputs (``writing``), a signal is only remembered, so a
second Ctrl-C or a SIGTERM sent after a SIGINT cannot cut a write short. Exit statuses:
``128 + signal`` (130 for Ctrl-C, 143 for SIGTERM), as a shell reports a process the signal
ended; ``--follow``, which runs until it is told to stop, exits 0.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

__all__ = ["Stopped", "StopSignals", "stop_name", "stop_status", "SIGNALS"]

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Stopped(KeyboardInterrupt):
    """A stop asked for by a signal (``signum``)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = int(signum)


def _signum(exc: BaseException) -> int:
    """The signal of a stop: a ``Stopped``'s, else SIGINT (a plain ``KeyboardInterrupt``)."""
    return getattr(exc, "signum", int(signal.SIGINT))


def stop_name(exc: BaseException) -> str:
    """``"Ctrl-C"`` or ``"SIGTERM"``: what stopped the run, for a person."""
    n = _signum(exc)
    return "Ctrl-C" if n == signal.SIGINT else signal.Signals(n).name


def stop_status(exc: BaseException) -> int:
    """The exit status of a run a signal stopped: ``128 + signal number`` (130, 143)."""
    return 128 + _signum(exc)


class StopSignals:
    """While entered: SIGINT and SIGTERM raise ``Stopped`` in the main thread (once; later
    signals are remembered in ``received`` only). Outside the main thread (where Python cannot
    set handlers) it does nothing, and a signal the process was started ignoring (a
    background job's SIGINT) stays ignored; the previous handlers come back on exit."""

    def __init__(self):
        self.received: int | None = None
        self._armed = False
        self._old: dict = {}

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            for s in SIGNALS:
                if signal.getsignal(s) is not signal.SIG_IGN:  # left ignored, as Python does
                    self._old[s] = signal.signal(s, self._handle)
        self._armed = True
        return self

    def __exit__(self, *exc) -> None:
        self._armed = False
        for s, old in self._old.items():
            signal.signal(s, old)
        self._old.clear()

    def _handle(self, signum, frame) -> None:
        if self.received is None:
            self.received = int(signum)
        if self._armed:
            self._armed = False
            raise Stopped(signum)

    @contextmanager
    def writing(self):
        """The outputs are being written: a signal now is remembered, not raised."""
        self._armed = False
        yield
