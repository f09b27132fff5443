"""Progress for a person waiting at a terminal: what the command is doing, from the first second.

Everything goes to stderr and only when stderr is a terminal or when asked (``--progress``):
pipes, logs and tests see nothing. On a terminal a stage shows a spinner with the seconds
elapsed, rewritten in place, then one line with its duration; asked for on a non-terminal, a
stage prints one line when it starts and one when it ends (no carriage returns in a log).
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager

from mfcl_jax.robot.signals import checkpoint

__all__ = ["Progress", "COMPILING", "NOTE_EVERY_S"]

COMPILING = "compiling (first run only; cached afterwards)"
NOTE_EVERY_S = 5.0
_FRAMES = "|/-\\"


class Progress:
    """Stage messages, spinners and window bars on stderr.

    Args:
        enabled: ``True`` forces progress on, ``None`` shows it when ``stream`` is a terminal,
            ``False`` silences it.
        stream: where to write (default ``sys.stderr``).
    """

    def __init__(self, enabled: bool | None = None, stream=None):
        self.stream = stream or sys.stderr
        tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.enabled = tty if enabled is None else bool(enabled)
        self.animate = self.enabled and tty

    def _write(self, text: str) -> None:
        self.stream.write(text)
        self.stream.flush()

    def note(self, text: str) -> None:
        """One line (when enabled)."""
        if self.enabled:
            self._write(f"mfcl: {text}\n")

    @contextmanager
    def stage(self, text: str):
        """A stage of work: a spinner (terminal) or a start line, then its duration. A stop
        signal whose exception was lost is raised as the stage starts or ends
        (``signals.checkpoint``)."""
        checkpoint()
        if not self.enabled:
            yield
            checkpoint()
            return
        t0 = time.monotonic()
        stop = threading.Event()
        spinner = None
        if self.animate:

            def spin():
                i = 0
                while not stop.wait(0.1):
                    dt = time.monotonic() - t0
                    self._write(f"\r{_FRAMES[i % 4]} {text} {dt:.0f} s\x1b[K")
                    i += 1

            spinner = threading.Thread(target=spin, daemon=True)
            spinner.start()
        else:
            self._write(f"mfcl: {text} ...\n")
        ok = False
        try:
            yield
            checkpoint()
            ok = True
        finally:
            stop.set()
            if spinner is not None:
                spinner.join()
                self._write("\r\x1b[K")
            end = "done" if ok else "stopped"
            self._write(f"mfcl: {text}: {end} in {time.monotonic() - t0:.1f} s\n")

    def track(self, items: Iterable, total: int | None, first: str = COMPILING) -> Iterator:
        """``items`` (windows) with progress: the first is computed inside ``stage(first)``
        (it compiles the kernels), the others under a bar of ``total`` (``None``: a count)
        on a terminal, else with a line every ``NOTE_EVERY_S`` seconds."""
        it = iter(items)
        with self.stage(first):
            head = next(it, _END)
        if head is _END:
            return
        if self.animate:
            with self.bar(total) as bar:
                yield head
                bar.update(1)
                for item in it:
                    checkpoint()
                    yield item
                    bar.update(1)
            return
        last, of = time.monotonic(), "" if total is None else f" of {total}"
        yield head
        for i, item in enumerate(it, 2):
            checkpoint()
            yield item
            if time.monotonic() - last >= NOTE_EVERY_S:
                self.note(f"window {i}{of}")
                last = time.monotonic()

    @contextmanager
    def counted(self, text: str, total: int):
        """A stage that counts its ``total`` steps: yields a callback ``done(n_done)``; a bar
        on a terminal, else ``stage(text)``."""
        if not self.animate:
            with self.stage(text):
                yield lambda n_done: None
            return
        self.note(text)
        with self.bar(total) as bar:
            yield lambda n_done: bar.update(n_done - bar.n)

    def echo(self, line: str, file=None) -> None:
        """Prints ``line`` (to ``file``, default stdout) without breaking a bar on the way."""
        from tqdm import tqdm

        tqdm.write(line, file=file or sys.stdout)

    def bar(self, total: int | None, unit: str = "window"):
        """A ``tqdm`` bar on a terminal (disabled, but still usable, elsewhere)."""
        from tqdm import tqdm

        return tqdm(
            total=total,
            file=self.stream,
            unit=unit,
            dynamic_ncols=True,
            disable=not self.animate,
        )


_END = object()
