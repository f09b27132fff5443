"""Ctrl-C (SIGINT) and SIGTERM (``systemd stop``, ``docker stop``, ``timeout``) stop a
``mfcl localize`` run the same way, in every mode: the work stops, and what was decided so far
is written (atomically, like a finished run's output).

``StopSignals.run(work)`` runs the work with SIGINT and SIGTERM turned into ``Stopped`` (a
``KeyboardInterrupt``) raised where the run is, and returns the stop (or None). Python drops
an exception raised inside a garbage-collector callback ("Exception ignored in ..."), which
a signal during JAX's compilation can hit: the signal is remembered (and not printed as an
error), raised again at the next ``checkpoint()`` (every progress stage and window passes
one), and a run that still ends normally is reported as stopped by it all the same. Once the
run writes its outputs (``writing``), a signal is only remembered, so a second Ctrl-C or a
SIGTERM sent after a SIGINT cannot cut a write short; after the command, a signal ends the
process at once with its status (``exit_on_signal``: no traceback from the interpreter's
shutdown; in the interpreter's very last moments the signal's default action ends it, which a
shell reports as the same status). Exit statuses:
``128 + signal`` (130 for Ctrl-C, 143 for SIGTERM), as a shell reports a process the signal
ended; ``--follow``, which runs until it is told to stop, exits 0.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager

__all__ = [
    "Stopped",
    "StopSignals",
    "checkpoint",
    "exit_on_signal",
    "stop_name",
    "stop_status",
    "SIGNALS",
]

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


_ACTIVE: list = []  # the StopSignals entered (innermost last)


def checkpoint() -> None:
    """Raises ``Stopped`` when a signal arrived during the running work and its exception was
    lost (raised inside a callback that Python ignores exceptions of); a no-op otherwise."""
    if _ACTIVE:
        _ACTIVE[-1].check()


@contextmanager
def atomic():
    """A step a stop must not split (a window's record kept and its line shown): a signal
    during it is raised right after it."""
    s = _ACTIVE[-1] if _ACTIVE else None
    if s is None or not s._armed:
        yield
        return
    s._armed = False
    try:
        yield
    finally:
        s.arm()


class StopSignals:
    """While entered: SIGINT and SIGTERM raise ``Stopped`` in the main thread, once (armed
    until the first stop, ``run``'s end or ``writing``; a later signal is remembered in
    ``received`` only). A stop not seen by the run yet (its exception dropped by Python, or a
    signal during a mid-run ``writing``) is owed: ``checkpoint`` and ``arm`` raise it.
    Outside the main thread (where Python cannot set handlers) it does nothing, and a signal
    the process was started ignoring (a background job's SIGINT) stays ignored; the previous
    handlers come back on exit."""

    def __init__(self):
        self.received: int | None = None
        self.dropped = 0  # stops whose exception Python dropped (then owed)
        self._armed = False
        self._owed = False
        self._old: dict = {}
        self._hook = None

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            for s in SIGNALS:
                if signal.getsignal(s) is not signal.SIG_IGN:  # left ignored, as Python does
                    self._old[s] = signal.signal(s, self._handle)
        self._armed = True
        _ACTIVE.append(self)
        self._hook = sys.unraisablehook
        sys.unraisablehook = self._unraisable
        return self

    def _unraisable(self, u) -> None:
        """A stop dropped by Python (raised in a callback) is owed, not printed as an error."""
        if u.exc_type is not None and issubclass(u.exc_type, Stopped):
            self.dropped += 1
            return
        self._hook(u)

    def __exit__(self, *exc) -> None:
        self._armed = False
        if self in _ACTIVE:
            _ACTIVE.remove(self)
        if self._hook is not None and sys.unraisablehook == self._unraisable:
            sys.unraisablehook = self._hook
        for s, old in self._old.items():
            signal.signal(s, old)
        self._old.clear()

    def _handle(self, signum, frame) -> None:
        if self.received is None:
            self.received = int(signum)
        self._owed = True  # until the run sees it
        if self._armed:
            self._armed = False
            raise Stopped(self.received)

    def check(self) -> None:
        """``checkpoint`` for this run: raises a stop the run has not seen."""
        if self._owed:
            self._owed = self._armed = False
            raise Stopped(self.received)

    def run(self, work) -> Stopped | KeyboardInterrupt | None:
        """Calls ``work()``; returns the stop that ended it (None when it ended by itself and
        no signal arrived: a stop whose exception was dropped still counts). Exceptions other
        than a stop propagate."""
        try:
            work()
        except KeyboardInterrupt as e:
            self._owed = self._armed = False
            return e
        self._owed = self._armed = False
        return Stopped(self.received) if self.received is not None else None

    def arm(self) -> None:
        """After a ``writing`` in the middle of the run: signals raise again (one that came
        during the write is raised now)."""
        self._armed = True
        self.check()

    @contextmanager
    def writing(self):
        """The outputs are being written: a signal now is remembered, not raised."""
        self._armed = False
        yield


def exit_on_signal() -> None:
    """From now on SIGINT / SIGTERM end the process at once with ``128 + signal`` (the
    command's outputs are written; the interpreter's shutdown is cut short, no traceback)."""
    if threading.current_thread() is not threading.main_thread():
        return

    def leave(signum, frame):
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError, RuntimeError):
                pass
        os._exit(128 + signum)

    for s in SIGNALS:
        if signal.getsignal(s) is not signal.SIG_IGN:
            signal.signal(s, leave)
