"""Memory: the budget a batch runs within (``--max-memory``), and the process's resident
memory measured while it runs (Linux ``/proc``; elsewhere ``getrusage``'s peak).

The default budget is a safe share of what the machine (or its cgroup, as in a container)
can give this process: ``DEFAULT_SHARE`` of the memory available at the start plus what the
process already holds.
"""

from __future__ import annotations

import os
import resource
import threading
from pathlib import Path

from mfcl_jax.io.errors import DataError

__all__ = ["DEFAULT_SHARE", "parse_size", "default_budget", "resident", "PeakSampler", "gib"]

DEFAULT_SHARE = 0.7
_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


def gib(n: float) -> str:
    """``n`` bytes as ``"1.23 GiB"``."""
    return f"{n / 2**30:.2f} GiB"


def parse_size(text: str, where: str = "--max-memory") -> int:
    """Bytes of ``"6G"``, ``"6GB"``, ``"6GiB"``, ``"512M"``, ``"1.5T"`` or ``"60%"`` (of the
    machine's memory: ``machine_memory``).

    Raises:
        DataError: naming ``where`` and the value.
    """
    t = str(text).strip().upper().replace("IB", "").replace("B", "")
    try:
        if t.endswith("%"):
            share = float(t[:-1]) / 100.0
            if not 0.0 < share <= 1.0:
                raise ValueError
            return int(share * machine_memory())
        unit = t[-1] if t and t[-1] in _UNITS else ""
        value = float(t[: len(t) - len(unit)])
        if not value > 0:
            raise ValueError
        return int(value * _UNITS[unit])
    except (ValueError, IndexError):
        raise DataError(
            f"{where}: {text!r} is not a memory size; give e.g. 6G, 512M or 60%"
        ) from None


def _meminfo(key: str) -> int | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def _cgroup_limit() -> int | None:
    for f in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            v = Path(f).read_text().strip()
        except OSError:
            continue
        if v.isdigit() and int(v) < 2**60:
            return int(v)
    return None


def machine_memory() -> int:
    """The memory this process may use at most: the machine's, or its cgroup's limit."""
    total = _meminfo("MemTotal") or 8 * 2**30
    limit = _cgroup_limit()
    return min(total, limit) if limit else total


def default_budget() -> int:
    """``DEFAULT_SHARE`` of (the memory available now + what this process holds), within
    the machine's (or cgroup's) memory."""
    avail = _meminfo("MemAvailable")
    if avail is None:
        avail = machine_memory()
    return int(DEFAULT_SHARE * min(avail + resident(), machine_memory()))


def resident() -> int:
    """The process's resident memory now (bytes; its peak so far where ``/proc`` is absent)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


class PeakSampler:
    """The highest resident memory seen while entered (sampled every ``every`` s by a
    thread; ``peak`` after exit)."""

    def __init__(self, every: float = 0.05):
        self.every, self.peak = every, 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _loop(self) -> None:
        while not self._stop.wait(self.every):
            self.peak = max(self.peak, resident())

    def __enter__(self) -> PeakSampler:
        self.peak = resident()
        self._thread = threading.Thread(target=self._loop, daemon=True, name="mfcl-memory")
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self.peak = max(self.peak, resident())
