"""The uniqueness test's ratio against what the layer reported, window by window.

The test (``decision.uniqueness``) compares the best placement of the whole path with the best
one outside its neighbourhood: ``llr = L(A*) - L(competitor)``. Under its observation model a
wrong placement reaches a ratio ``llr`` against the truth with probability at most
``exp(-llr)`` (Wald's bound), so a lane with error rate ``alpha`` commits at
``llr >= log(1 / alpha)``. This table checks the model where it matters: in every window where
the test ran and no veto held, was ``A*`` (the placement a lane commits to when the test holds,
``test_correct``) right or wrong, binned by the ratio. A wrong ``A*`` in a bin above a lane's
threshold is a false commit that lane would have made or did make. Tables written before
``A*`` was recorded judge the layer's reported anchor instead (``correct``: the window's
champion, within the grouping tolerance of ``A*`` by a veto, or the commit itself), which can
be wrong by a few degrees where ``A*``, fitted to the whole path, is not.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["EDGES", "ratio_calibration"]

# bin edges: 1, 2, 3 nats, then the thresholds of the lanes (alpha 1e-2, 1e-3, 1e-4, 1e-6)
EDGES = (0.0, 1.0, 2.0, 3.0, math.log(1e2), math.log(1e3), math.log(1e4), math.log(1e6), math.inf)


def ratio_calibration(windows: pd.DataFrame, policy: str = "ours_unique_a6") -> pd.DataFrame:
    """Per ratio bin: tested windows and wrong anchors, nominal runs and fault rows apart.

    Args:
        windows: the benchmark's per-window table (``windows.csv.gz``: ``policy, fault, llr,
            test_correct`` or, in older tables, ``correct``).
        policy: the lane read (the test is shared by the uniqueness lanes; ``alpha = 1e-6``
            keeps testing longest, as it commits last).

    Returns:
        One row per bin ``[llr_from, llr_to)``: ``bound`` (``exp(-llr_from)``, the model's
        bound for one wrong placement), ``windows`` and ``wrong`` (nominal: windows tested
        unvetoed and judged, and of them the anchor past the false-commit line),
        ``fault_windows`` and ``fault_wrong`` (the same over the fault rows).
    """
    judged = "test_correct" if "test_correct" in windows else "correct"
    w = windows[(windows["policy"] == policy) & windows["llr"].notna()]
    w = w[(w["llr"] > -np.inf) & w[judged].notna()]
    fault = w["fault"].fillna("").astype(str) != ""
    wrong = ~w[judged].astype(bool)
    rows = []
    for lo, hi in zip(EDGES[:-1], EDGES[1:], strict=True):
        b = (w["llr"] >= lo) & (w["llr"] < hi) if hi < math.inf else w["llr"] >= lo
        rows.append(dict(
            llr_from=round(lo, 2), llr_to=round(hi, 2), bound=math.exp(-lo),
            windows=int((b & ~fault).sum()), wrong=int((b & ~fault & wrong).sum()),
            fault_windows=int((b & fault).sum()), fault_wrong=int((b & fault & wrong).sum()),
        ))  # fmt: skip
    return pd.DataFrame(rows)
