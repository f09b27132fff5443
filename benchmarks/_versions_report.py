"""What ``benchmarks/versions.py`` writes: the summary (medians per case, phase and side,
ratio old/new, peak resident memory), the CSV of every run, the Markdown table, the figure and
the ``bench_versions`` block of the docs page."""

from __future__ import annotations

import pathlib
import statistics

from benchmarks._versions_sides import SIDES, log


def _median(values) -> float:
    values = [v for v in values if v is not None and v == v]  # drops None and NaN
    return statistics.median(values) if values else float("nan")


def summarize(rows, notes) -> list[dict]:
    """Median per (case, phase, metric) and side; ratio old/new; peak resident memory (the
    maximum over the runs of that case and phase) per side."""
    import pandas as pd

    if not rows:
        return []
    df = pd.DataFrame(rows)
    last = df.groupby("case")["phase"].last().to_dict()
    out = []
    for (case, phase), g in df.groupby(["case", "phase"], sort=False):
        metrics = [("wall", "wall_s")]
        if "first_line_s" in g and g["first_line_s"].notna().any():
            metrics.append(("first status line", "first_line_s"))
        for label, col in metrics:
            med = {s: _median(g[g.side == s][col]) for s in SIDES}
            rss = {s: g[g.side == s]["max_rss_mib"].max() for s in SIDES}
            n = {s: int((g.side == s).sum()) for s in SIDES}
            note = [f"n={n['new']}" if n["old"] == n["new"] else f"n={n['old']} / {n['new']}"]
            if col == "wall_s":
                if "windows" in g and g["windows"].notna().any():
                    w = {s: g[g.side == s]["windows"].dropna() for s in SIDES}
                    w = {s: f"{int(v.iloc[0])}" if len(v) else "-" for s, v in w.items()}
                    note.append(f"{w['old']} / {w['new']} windows")
                if case in notes and phase == last[case]:  # compares the last runs' outputs
                    note.append(notes[case])
            out.append(dict(case=f"{case} {phase} ({label})", old=med["old"], new=med["new"],
                            ratio=med["old"] / med["new"] if med["new"] else float("nan"),
                            rss_old=rss["old"] if col == "wall_s" else float("nan"),
                            rss_new=rss["new"] if col == "wall_s" else float("nan"),
                            notes="; ".join(note)))  # fmt: skip
    return out


def write_rows(rows, csv_path: pathlib.Path) -> None:
    import pandas as pd

    csv_path.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(csv_path, index=False, float_format="%.4g")


def _num(x: float, fmt: str) -> str:
    return "-" if x != x else format(x, fmt)  # NaN: "-"


def write_outputs(rows, summary, header: str, csv_path: pathlib.Path) -> pathlib.Path:
    """The CSV of every run, the Markdown table of medians and the figure; returns the
    Markdown's path."""
    write_rows(rows, csv_path)
    md = [header, "",
          "| case | old median s | new median s | ratio old/new | peak RSS old / new, MiB "
          "| notes |",
          "|:--|--:|--:|--:|--:|:--|"]  # fmt: skip
    md += [f"| {r['case']} | {_num(r['old'], '.1f')} | {_num(r['new'], '.1f')} | "
           f"{_num(r['ratio'], '.2f')} | "
           + ("" if r["rss_new"] != r["rss_new"] and r["rss_old"] != r["rss_old"]
              else f"{_num(r['rss_old'], '.0f')} / {_num(r['rss_new'], '.0f')}")
           + f" | {r['notes']} |"
           for r in summary]  # fmt: skip
    md_path = csv_path.with_suffix(".md")
    md_path.write_text("\n".join(md) + "\n")
    print("\n".join(md), flush=True)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import numpy as np

        x = np.arange(len(summary))
        fig, ax = plt.subplots(figsize=(max(6, 1.1 * len(summary) + 2), 4.2))
        ax.bar(x - 0.2, [r["old"] for r in summary], 0.4, label="old", color="#999999")
        ax.bar(x + 0.2, [r["new"] for r in summary], 0.4, label="new", color="#2b6cb0")
        for i, r in enumerate(summary):
            top = np.nanmax([r["old"], r["new"], 1e-3]) * 1.05
            ax.text(i, top, f"x{r['ratio']:.2f}", ha="center", fontsize=8)
        ax.set_xticks(x, [r["case"].replace(" (", "\n(") for r in summary], fontsize=7)
        ax.set_ylabel("median seconds")
        ax.set_yscale("log")
        ax.set_title("old vs new code, same machine, one run (label: old / new)", fontsize=10)
        ax.legend()
        fig.tight_layout()
        fig.savefig(csv_path.with_suffix(".png"), dpi=130)
        plt.close(fig)
    except Exception as e:  # the figure is optional
        log(f"figure not written: {e}")
    return md_path


def paste_into_docs(md_path: pathlib.Path, page: pathlib.Path) -> bool:
    """Pastes ``md_path`` into the ``<!-- BEGIN:bench_versions -->`` block of ``page`` (no
    other block of the page is touched)."""
    from mfcl_jax.study.readme import update_block

    return update_block(page, "bench_versions", md_path)
