"""The figure of ``benchmarks/frontend.py`` (``results/frontend.png``): top-1 error histogram,
recall and top-1 against d_s, refinement errors, stage profile."""

from __future__ import annotations

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from benchmarks._frontend_data import CHUNK, P_STUDY  # noqa: E402


def figure(df, ed, tdf, p, path):
    fig, ax = plt.subplots(1, 4, figsize=(21, 4.2))
    for name, g in ed.groupby("scene"):
        ax[0].hist(
            np.clip(g.top1_err_m, 1e-3, 30), bins=np.geomspace(1e-3, 30, 60), alpha=0.6, label=name
        )
    for x, lab in ((7.3, "bay 7.3 m"), (14.4, "room 14.4 m")):
        ax[0].axvline(x, color="k", ls=":", lw=0.8)
        ax[0].text(x, ax[0].get_ylim()[1] * 0.9, lab, rotation=90, fontsize=7, ha="right")
    ax[0].set_xscale("log")
    ax[0].set_xlabel("top-1 position error (m)")
    ax[0].set_ylabel("submaps")
    ax[0].legend(fontsize=8)
    for name, g in df.groupby("scene"):
        ax[1].plot(g.d_s, g.recall_at_J, "o-", label=f"{name} recall@{p.J}")
        ax[1].plot(g.d_s, g.top1, "s--", label=f"{name} top-1")
    ax[1].axhline(0.95, color="k", ls=":", lw=0.8)
    ax[1].set_xlabel("d_s (m)")
    ax[1].set_ylim(0, 1.05)
    ax[1].legend(fontsize=8)
    x = np.arange(len(df))
    lab = [f"{s[:5]} {d:g}" for s, d in zip(df.scene, df.d_s, strict=True)]
    ax[2].bar(x - 0.2, 100 * df.err_before_m, 0.4, label="before refinement (median)")
    ax[2].bar(x + 0.2, 100 * df.err_after_m, 0.4, label="after (same candidate)")
    ax[2].errorbar(x - 0.2, 100 * df.err_before_p90_m, fmt="k_", label="90th pct")
    ax[2].errorbar(x + 0.2, 100 * df.err_after_p90_m, fmt="k_")
    ax[2].set_xticks(x, lab, rotation=30, fontsize=8)
    ax[2].set_ylabel("position error of the true candidate (cm)")
    ax[2].legend(fontsize=8)
    st = tdf[tdf.kind == "stage"]
    ax[3].barh(st.stage, st.ms_per_submap)
    ax[3].invert_yaxis()
    total = st.ms_cumulative.max()
    ax[3].set_xlabel(f"ms per submap (chunk {CHUNK}, P {P_STUDY}; total {total:.1f})")
    ax[3].set_title("stage profile (one run, interleaved medians)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
