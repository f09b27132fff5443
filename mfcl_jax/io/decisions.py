"""Decisions as JSON lines (ARCHITECTURE.md): one object per submap window.

Each line holds ``k, t, state, anchor, symmetry, tau, B1, B2, margin`` and, in files written
since ``mfcl localize`` reports them, ``pose`` (the robot's pose ``{x, y, yaw_deg}`` in the
plan frame when COMMIT, else null), ``reason`` (why a DEFER / AMBIGUOUS, ``""`` when
none) and ``alternatives`` (when AMBIGUOUS: the robot's pose ``{x, y, yaw_deg}`` in the plan
frame under each explanation the layer could not tell apart, best first: the consensus winner
``T*``, then the strongest competitor; null for other states), ``unique`` (``mfcl localize
--early-commit`` only: ``{llr, needed}``, the uniqueness test's ratio at the window, null where
it did not run, "inf" / "-inf" where nothing competed / a veto held, and the ratio a commit
needs) and ``segment`` (the odometry
segment of the window: 0, plus one after every odometry jump; ``k`` is the window's index over
the whole recording, it does not start again in a new segment). Files without the optional
keys still read; a line that has them is checked.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from mfcl_jax.io.atomic import atomic_write_text
from mfcl_jax.io.errors import DataError

__all__ = ["write_decisions", "read_decisions", "decision_line", "STATES", "SYMMETRIES"]

STATES = ("COMMIT", "DEFER", "AMBIGUOUS")
SYMMETRIES = (None, "translation", "rotation", "mirror", "multimodal", "storey")
_KEYS = ("k", "t", "state", "anchor", "symmetry", "tau", "B1", "B2", "margin")
_OPTIONAL = ("segment", "pose", "reason", "alternatives", "unique", "storey", "storeys")
# The order of the keys on a line: the window and its segment first.
_ORDER = ("k", "segment", *_KEYS[1:], *_OPTIONAL[1:])


def _check_pose(where: str, name: str, a) -> None:
    if a is None:
        return
    if not isinstance(a, dict) or set(a) != {"x", "y", "yaw_deg"}:
        raise DataError(f"{where}: {name}={a!r}, expected {{x, y, yaw_deg}} or null")
    if not all(isinstance(a[k], int | float) and math.isfinite(a[k]) for k in a):
        raise DataError(f"{where}: {name}={a!r} has a non-finite value")


def _number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _check_unique(where: str, u) -> None:
    if not isinstance(u, dict) or set(u) != {"llr", "needed"}:
        raise DataError(f"{where}: unique={u!r}, expected {{llr, needed}} or null")
    if not (u["llr"] is None or u["llr"] in ("inf", "-inf") or _number(u["llr"])):
        raise DataError(f"{where}: unique.llr={u['llr']!r}, expected a number, "
                        '"inf", "-inf" or null')  # fmt: skip
    if not (_number(u["needed"]) and u["needed"] > 0):
        raise DataError(f"{where}: unique.needed={u['needed']!r}, expected a number > 0")


def _check_storeys(where: str, d: dict) -> None:
    """``storey`` (a name, or null) and ``storeys`` (a list of names, or null) of a plan of
    several storeys: a COMMIT names one storey, and it is the one ``storeys`` lists."""
    if "storey" in d and d["storey"] is not None and not isinstance(d["storey"], str):
        raise DataError(f"{where}: storey={d['storey']!r}, expected a storey name or null")
    names = d.get("storeys")
    if names is not None and (
        not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names)
    ):
        raise DataError(f"{where}: storeys={names!r}, expected a list of storey names or null")
    if "storey" in d and d["state"] == "COMMIT" and (d["storey"] is None or names != [d["storey"]]):
        raise DataError(f"{where}: a COMMIT names its storey: storey={d['storey']!r}, "
                        f"storeys={names!r}")  # fmt: skip


def _check(where: str, d: dict) -> dict:
    missing = [k for k in _KEYS if k not in d]
    if missing:
        raise DataError(f"{where}: missing keys {missing}")
    if not isinstance(d["k"], int) or isinstance(d["k"], bool):
        raise DataError(f"{where}: k={d['k']!r}, expected an integer (the window's index)")
    if d["t"] is not None and not _number(d["t"]):
        raise DataError(f"{where}: t={d['t']!r}, expected a finite time in seconds")
    if d["state"] not in STATES:
        raise DataError(f"{where}: state={d['state']!r}, expected one of {STATES}")
    if d["symmetry"] not in SYMMETRIES:
        raise DataError(f"{where}: symmetry={d['symmetry']!r}, expected one of {SYMMETRIES}")
    a = d["anchor"]
    _check_pose(where, "anchor", a)
    if d["state"] == "COMMIT" and a is None:
        raise DataError(f"{where}: a COMMIT needs an anchor")
    if "pose" in d:
        _check_pose(where, "pose", d["pose"])
        if (d["pose"] is None) == (d["state"] == "COMMIT"):
            raise DataError(
                f"{where}: pose={d['pose']!r} with state={d['state']!r}; a pose is given "
                "exactly when the state is COMMIT"
            )
    if "alternatives" in d and d["alternatives"] is not None:
        alt = d["alternatives"]
        if not isinstance(alt, list) or not alt:
            raise DataError(f"{where}: alternatives={alt!r}, expected a non-empty list or null")
        if d["state"] != "AMBIGUOUS":
            raise DataError(
                f"{where}: alternatives given with state={d['state']!r}; only an AMBIGUOUS "
                "decision lists them"
            )
        for i, a in enumerate(alt):
            if a is None:
                raise DataError(f"{where}: alternatives[{i}] is null, expected {{x, y, yaw_deg}}")
            if isinstance(a, dict) and "storey" in a:
                if a["storey"] is not None and not isinstance(a["storey"], str):
                    raise DataError(f"{where}: alternatives[{i}].storey={a['storey']!r}, "
                                    "expected a storey name or null")  # fmt: skip
                a = {k: v for k, v in a.items() if k != "storey"}
            _check_pose(where, f"alternatives[{i}]", a)
    if "segment" in d:
        seg = d["segment"]
        if not isinstance(seg, int) or isinstance(seg, bool) or seg < 0:
            raise DataError(f"{where}: segment={seg!r}, expected an integer >= 0")
    if "unique" in d and d["unique"] is not None:
        _check_unique(where, d["unique"])
    _check_storeys(where, d)
    if "reason" in d and not isinstance(d["reason"], str):
        raise DataError(f"{where}: reason={d['reason']!r}, expected a string")
    tau = d["tau"]
    if tau is not None and (not isinstance(tau, list) or len(tau) != 2):
        raise DataError(f"{where}: tau={tau!r}, expected [tx, ty] or null")
    return d


def decision_line(d: dict, where: str = "<decision>") -> str:
    """One validated JSON line (no newline) of a decision dict, keys in the file's order."""
    d = _check(where, dict(d))
    keys = [k for k in _ORDER if k in d]
    return json.dumps({k: d[k] for k in keys}, allow_nan=False)


def write_decisions(path, decisions) -> Path:
    """Writes decision dicts (keys ``k, t, state, anchor, symmetry, tau, B1, B2, margin`` and,
    when present, ``segment``, ``pose``, ``reason``, ``alternatives`` and ``unique``) as JSON lines,
    validated first and written atomically (all or nothing)."""
    path = Path(path)
    lines = [decision_line(d, f"{path}: decision #{i}") for i, d in enumerate(decisions)]
    return atomic_write_text(path, "\n".join(lines) + ("\n" if lines else ""))


def read_decisions(path) -> list[dict]:
    """Reads and validates a decisions JSON-lines file (errors name the file and line)."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    out, lines = [], []
    for no, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            d = json.loads(line)
        except json.JSONDecodeError as e:
            raise DataError(f"{path}:{no}: not valid JSON ({e})") from None
        if not isinstance(d, dict):
            raise DataError(f"{path}:{no}: expected a JSON object")
        out.append(_check(f"{path}:{no}", d))
        lines.append(no)
    _check_order(path, out, lines)
    return out


def _check_order(path, decisions: list[dict], lines: list[int]) -> None:
    """The windows of a file in the order they were decided: within an odometry segment
    (``segment`` where the file has it; a file without it starts a new segment wherever ``k``
    does not grow), ``k`` never repeats and grows line by line, and ``t`` never goes back."""
    seen: dict[tuple, int] = {}
    last: dict = {}
    segments = all("segment" in d for d in decisions)
    seg = 0
    for i, (d, no) in enumerate(zip(decisions, lines, strict=True)):
        k, t = d["k"], d["t"]
        if not segments and i and k <= decisions[i - 1]["k"]:
            seg += 1
        s = d["segment"] if segments else seg
        key = (s, k)
        if key in seen:
            raise DataError(
                f"{path}:{no}: k={k} repeats line {seen[key]}; a window is decided once"
            )
        seen[key] = no
        if s in last:
            pk, pt, pno = last[s]
            if k < pk:
                raise DataError(f"{path}:{no}: k={k} after k={pk} (line {pno}) in segment {s}; "
                                "windows are written in the order they are decided")  # fmt: skip
            if t is not None and pt is not None and t < pt:
                raise DataError(f"{path}:{no}: t={t} goes back from t={pt} (line {pno}) within "
                                f"odometry segment {s}")  # fmt: skip
        last[s] = (k, t, no)
