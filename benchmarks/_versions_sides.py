"""The two sides of ``benchmarks/versions.py`` as subprocesses: each side's environment (its
own tree first on ``PYTHONPATH``), the check that it imports its own ``mfcl_jax``, one command
timed under ``/usr/bin/time -v`` (wall time, first status line, peak resident memory), the
log line, and the machine's load and other heavy jobs."""

from __future__ import annotations

import datetime
import os
import pathlib
import re
import signal
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
OTHER_JOBS = "experiments.benchmark|experiments.real|pytest|experiments.sweep"
SIDES = ("old", "new")
TIME = "/usr/bin/time"  # GNU time: -v reports the peak resident set size


def log(msg: str) -> None:
    stamp = datetime.datetime.now().strftime("%H:%M:%S")
    print(f"[{stamp}] {msg}", flush=True)


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def other_jobs() -> list[str]:
    """Command lines of other heavy jobs on the machine (not this script's children)."""
    r = subprocess.run(["pgrep", "-af", OTHER_JOBS], capture_output=True, text=True)
    mine = {str(os.getpid())}
    return [ln for ln in r.stdout.splitlines() if ln and ln.split()[0] not in mine]


def side_env(tree: pathlib.Path, cache: pathlib.Path | None) -> dict:
    """The side's environment: its tree first on ``PYTHONPATH``; ``MFCL_CACHE_DIR`` (the
    ``mfcl`` command's persistent compilation cache) set to ``cache``. JAX's own
    ``JAX_COMPILATION_CACHE_DIR`` is removed, so the sweep (which turns no cache on) runs as
    it does for a user."""
    env = {**os.environ, "PYTHONPATH": str(tree), "PYTHONUNBUFFERED": "1"}
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    if cache is not None:
        env["MFCL_CACHE_DIR"] = str(cache)
    return env


def check_import(side: str, tree: pathlib.Path) -> str:
    """``mfcl_jax.__file__`` as the side's subprocess sees it; it must lie in ``tree``."""
    r = subprocess.run(
        [sys.executable, "-c", "import mfcl_jax; print(mfcl_jax.__file__)"],
        cwd=tree, env=side_env(tree, None), capture_output=True, text=True, check=True,
    )  # fmt: skip
    path = r.stdout.strip()
    ok = pathlib.Path(path).resolve().is_relative_to(tree.resolve())
    log(f"{side}: mfcl_jax from {path}" + ("" if ok else "  <-- NOT ITS OWN TREE"))
    if not ok:
        raise RuntimeError(f"{side} imports {path}, not its tree {tree}")
    return path


def timed(cmd, cwd, env, logfile: pathlib.Path, first_line: bool = False) -> dict:
    """Runs ``cmd`` under ``/usr/bin/time -v``; wall time, time to the first status line
    (``k=...`` on stdout, when ``first_line``) and the child's peak resident memory."""
    rusage = logfile.with_suffix(".time")
    full = [TIME, "-v", "-o", str(rusage), *cmd]
    first = None
    with open(logfile, "w") as out, open(logfile.with_suffix(".err"), "w") as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(full, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=err,
                             text=True, start_new_session=True)  # fmt: skip
        try:
            for line in p.stdout:
                if first is None and first_line and line.startswith("k="):  # a status line
                    first = time.perf_counter() - t0
                out.write(line)
            rc = p.wait()
        except BaseException:  # Ctrl-C: GNU time does not pass it on; end the whole group
            os.killpg(p.pid, signal.SIGTERM)
            p.wait()
            raise
        wall = time.perf_counter() - t0
    if rc != 0:
        tail = logfile.with_suffix(".err").read_text()[-3000:]
        raise RuntimeError(f"exit {rc}: {' '.join(map(str, cmd))}\n{tail}")
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", rusage.read_text())
    rss = int(m.group(1)) / 1024 if m else float("nan")
    return dict(wall_s=wall, first_line_s=first, max_rss_mib=rss)
