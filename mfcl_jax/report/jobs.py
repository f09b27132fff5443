"""The jobs of a Hydra multirun, read back to be merged: which job holds a repeated row.

Both merges (the study's ``study.run.merge``, the benchmark's ``bench.main.merge``) tag each
job's table with a ``_job`` column and refuse to merge jobs that hold the same run; this finds
the first such run and the jobs it is in, for the error that names them.
"""

from __future__ import annotations

import pandas as pd

__all__ = ["repeated", "where"]


def repeated(frame: pd.DataFrame, key: list[str], job: str = "_job"):
    """The first row of ``frame`` whose ``key`` appears more than once and the sorted jobs
    holding that key, or ``None`` if every key is unique (``key`` columns without NaN)."""
    twice = frame[frame.duplicated(key, keep=False)]
    if twice.empty:
        return None
    first = twice.iloc[0]
    same = (twice[key] == first[key]).all(axis=1)
    return first, sorted(set(twice.loc[same, job]))


def where(jobs: list[str]) -> str:
    """``"more than one job (a, b)"``, or ``"a twice"`` when the repeat is inside one job."""
    return f"more than one job ({', '.join(jobs)})" if len(jobs) > 1 else f"{jobs[0]} twice"
