"""Tables and figures of the study, from scored per-window decisions.

``build_tables`` needs only the scored windows (so a multirun merge can call it on the union of
its jobs' outputs); ``build_figures`` and the density test also need the simulated data.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from mfcl_jax.report import figures, tables
from mfcl_jax.score import first_commits
from mfcl_jax.sim.scenes import BAY_PITCH, get_scene
from mfcl_jax.study import paper

__all__ = ["KEYS", "firsts_of", "symmetric_summary", "build_tables", "build_figures"]

KEYS = ("scene", "trajectory", "d_s", "seed", "policy")


def firsts_of(scored: pd.DataFrame) -> pd.DataFrame:
    """First commit per scene x trajectory x d_s x seed x policy."""
    return first_commits(scored, keys=KEYS)


def symmetric_summary(firsts: pd.DataFrame, scored: pd.DataFrame) -> pd.DataFrame:
    """Symmetric scene per run: commit window and error with and without the probe, early
    commits as bay multiples, and the detected period's error against the true pitch."""
    f = firsts[(firsts["scene"] == "symmetric_bays") & firsts["policy"].isin(["ours", "no_probe"])]
    s = scored[(scored["scene"] == "symmetric_bays") & (scored["policy"] == "ours")]
    tau = np.hypot(s["tau_x"], s["tau_y"])
    s = s.assign(tau=tau)
    rows = []
    for (traj, ds, seed), g in f.groupby(["trajectory", "d_s", "seed"]):
        row = {"trajectory": traj, "d_s": ds, "seed": seed}
        for pol in ("ours", "no_probe"):
            r = g[g["policy"] == pol].iloc[0]
            row[f"{pol}_k"] = r["k"]
            row[f"{pol}_err_xy"] = r["err_xy"]
            row[f"{pol}_bays"] = r["err_xy"] / BAY_PITCH if r["committed"] else math.nan
            row[f"{pol}_correct"] = bool(r["correct"])
        row["n_windows"] = int(g["n_windows"].iloc[0])
        t = s[(s["trajectory"] == traj) & (s["d_s"] == ds) & (s["seed"] == seed)]["tau"].dropna()
        row["n_tau"] = len(t)
        row["tau_max_abs_err"] = float(np.max(np.abs(t - BAY_PITCH))) if len(t) else math.nan
        row["tau_mean_abs_err"] = float(np.mean(np.abs(t - BAY_PITCH))) if len(t) else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def congruence_table(scored: pd.DataFrame, strict: pd.DataFrame, strict_iou: float):
    """Our layer with the default room-congruence threshold vs a strict one, per scene."""
    from mfcl_jax.decision.maps import MIN_CONGRUENT_IOU

    rows = []
    for label, df in (
        (f"IoU >= {MIN_CONGRUENT_IOU:g} (default)", scored),
        (f"IoU >= {strict_iou:g} (strict)", strict),
    ):
        f = firsts_of(df[df["policy"] == "ours"])
        for scene, g in f.groupby("scene"):
            m = tables.selective_metrics(g, policies=("ours",)).iloc[0].to_dict()
            rows.append({"congruence": label, "scene": scene} | m)
    return pd.DataFrame(rows).drop(columns=["policy"])


def _fmt_commit(r) -> str:
    if not r["committed"]:
        return f"no commit ({r['final_state']})"
    return f"k={int(r['k'])}, {r['err_xy']:.2f} m ({r['err_xy'] / BAY_PITCH:.2f} tau)"


def build_tables(
    scored: pd.DataFrame,
    out,
    main_seed: int,
    density: pd.DataFrame | None = None,
    timings: pd.DataFrame | None = None,
) -> dict[str, pd.DataFrame]:
    """Builds and writes every table; returns them by name."""
    out = Path(out)
    firsts = firsts_of(scored)
    three = firsts[firsts["scene"] == "three_rooms"]
    t: dict[str, pd.DataFrame] = {}
    if len(three):
        t["policy_table"] = tables.policy_table(three, seed=main_seed)
        t["policy_rates"] = tables.policy_rates(three)
        t["selective_metrics"] = tables.selective_metrics(three)
        t["ablation"] = tables.ablation(three)
        t["sensitivity"] = tables.sensitivity(three)
    sym = firsts[firsts["scene"] == "symmetric_bays"]
    if len(sym):
        t["symmetric_sim"] = symmetric_summary(firsts, scored)
        ds_main = 6.0 if 6.0 in set(scored["d_s"]) else float(scored["d_s"].min())
        t["symmetric_windows"] = tables.symmetric_sim(
            scored[scored["scene"] == "symmetric_bays"], BAY_PITCH, main_seed, ds_main
        )
        t["symmetric_metrics"] = tables.selective_metrics(sym, policies=("ours", "no_probe"))
    if density is not None:
        t["density_immunity"] = density
    extra = _extras(firsts, t, main_seed)
    if len(three):
        t["paper_comparison"] = paper.comparison(three[three["seed"] == main_seed], three, extra)
    if timings is not None:
        t["timings"] = timings
    out.mkdir(parents=True, exist_ok=True)
    firsts.to_csv(out / "per_seed.csv", index=False, float_format="%.4g")
    for name, df in t.items():
        tables.write_table(df, out, name, latex=name in ("policy_table", "selective_metrics"))
    return t


def _extras(firsts, t, main_seed) -> dict:
    """Our values for the paper's text-only claims."""
    ex = {}
    three = firsts[firsts["scene"] == "three_rooms"]
    for pol, key in (
        ("gate_only", "gate_only correct"),
        ("consensus_only", "consensus_only correct"),
        ("ours", "full (ours) correct"),
    ):
        m = three[(three["policy"] == pol) & (three["seed"] == main_seed)]
        a = three[three["policy"] == pol]
        ex[("ablation", key)] = f"{int(m['correct'].sum())}/{len(m)}"
        ex[("ablation", key, "all")] = f"{int(a['correct'].sum())}/{len(a)}"
    parts, parts_all = [], []
    for pol in ("ours_b2_d1", "ours", "ours_b4_d2"):
        m = three[(three["policy"] == pol) & (three["seed"] == main_seed)]
        a = three[three["policy"] == pol]
        parts.append(f"{int(m['correct'].sum())}/{len(m)} ({int(m['false_commit'].sum())} false)")
        parts_all.append(
            f"{int(a['correct'].sum())}/{len(a)} ({int(a['false_commit'].sum())} false)"
        )
    ex[("sensitivity", "(2,1) / (3,2) / (4,2) correct")] = " / ".join(parts)
    ex[("sensitivity", "(2,1) / (3,2) / (4,2) correct", "all")] = " / ".join(parts_all)
    ok = three[(three["policy"] == "ours") & three["correct"]]
    if len(ok):
        m = ok[ok["seed"] == main_seed]
        if len(m):
            ex[("real", "ours commit errors / yaw")] = _err_range(m)
        ex[("real", "ours commit errors / yaw", "all")] = _err_range(ok)
    if "density_immunity" in t:
        d = t["density_immunity"]
        ours = d[d["policy"] == "ours"]
        sup = d[d["policy"] == "support"]
        same = all(
            ours.iloc[0][c] == ours.iloc[1][c]
            or (pd.isna(ours.iloc[0][c]) and pd.isna(ours.iloc[1][c]))
            for c in ("state_at_k", "room", "x", "y", "yaw_deg", "B1", "margin", "first_commit_k")
        )
        pools = f"{int(ours.iloc[0]['candidates_to_k'])} -> {int(ours.iloc[1]['candidates_to_k'])}"
        ex[("density", "pool growth at commit window")] = (
            f"{pools}; ours {'unchanged' if same else 'CHANGED'}; "
            f"support {sup.iloc[0]['state_at_k']}/"
            f"{sup.iloc[0]['room']} -> {sup.iloc[1]['state_at_k']}/{sup.iloc[1]['room']}"
        )
    if "symmetric_sim" in t:
        s = t["symmetric_sim"]
        ds_main = 6.0 if 6.0 in set(s["d_s"]) else float(s["d_s"].min())
        sm = firsts[
            (firsts["scene"] == "symmetric_bays")
            & (firsts["seed"] == main_seed)
            & (firsts["d_s"] == ds_main)
        ]
        for i, traj in enumerate(sorted(sm["trajectory"].unique())):
            which = "main start" if i == 0 else "second start"
            o = sm[(sm["trajectory"] == traj) & (sm["policy"] == "ours")].iloc[0]
            n = sm[(sm["trajectory"] == traj) & (sm["policy"] == "no_probe")].iloc[0]
            ex[("symmetric", f"{which}: ours commit window, error")] = (
                f"{_fmt_commit(o)} of {int(o['n_windows'])} windows"
            )
            ex[("symmetric", f"{which}: no-probe early commit")] = _fmt_commit(n)
        sa = s.dropna(subset=["tau_max_abs_err"])
        if len(sa):
            worst, mean = sa["tau_max_abs_err"].max(), sa["tau_mean_abs_err"].mean()
            ex[("symmetric", "tau error vs 7.30 m")] = f"max {worst:.2f} m, mean abs {mean:.2f} m"
        allo = firsts[(firsts["scene"] == "symmetric_bays") & (firsts["policy"] == "ours")]
        alln = firsts[(firsts["scene"] == "symmetric_bays") & (firsts["policy"] == "no_probe")]
        ex[("symmetric", "main start: ours commit window, error", "all")] = _tally(allo)
        ex[("symmetric", "main start: no-probe early commit", "all")] = _tally(alln)
    return ex


def _err_range(f: pd.DataFrame) -> str:
    lo, hi, yaw = f["err_xy"].min(), f["err_xy"].max(), f["err_yaw_deg"].max()
    return f"{lo:.2f}-{hi:.2f} m, < {yaw:.2f} deg"


def _tally(f: pd.DataFrame) -> str:
    return f"correct {int(f['correct'].sum())}/{len(f)}, false {int(f['false_commit'].sum())}"


def build_figures(scored, data, cands, out, main_seed: int) -> list[Path]:
    """Draws every figure of the study into ``out``."""
    out = Path(out)
    paths = []
    firsts = firsts_of(scored)
    sym = scored[(scored["scene"] == "symmetric_bays") & (scored["seed"] == main_seed)]
    if len(sym):
        ds = 6.0 if 6.0 in set(sym["d_s"]) else float(sym["d_s"].min())
        fig = figures.state_timeline(
            sym[sym["d_s"] == ds], BAY_PITCH, f"symmetric_bays, d_s={ds:g} m, seed {main_seed}"
        )
        paths.append(figures.save(fig, out / "symmetric_states.png"))
    three = scored[(scored["scene"] == "three_rooms") & (scored["seed"] == main_seed)]
    if len(three):
        ds = 6.0 if 6.0 in set(three["d_s"]) else float(three["d_s"].min())
        paths.append(_clouds(three[three["d_s"] == ds], firsts, data, out, ds))
        paths.append(_anchor_space(three[three["d_s"] == ds], data, cands, out, ds))
    fig = figures.risk_coverage(firsts)
    paths.append(figures.save(fig, out / "risk_coverage.png"))
    return paths


def _row_of(data, scored_run_row):
    r = int(scored_run_row["run"])
    k = int(scored_run_row["k"])
    sub = int(np.asarray(data.batch.runs.submap)[r, k - 1])
    return r, k, sub


def _clouds(scored, firsts, data, out, ds):
    scene = get_scene("three_rooms")
    panels = []
    for traj in sorted(scored["trajectory"].unique()):
        clouds = []
        truth_xy = None
        for pol, colour in (("single_shot", "tab:red"), ("ours", "tab:green")):
            g = scored[
                (scored["trajectory"] == traj)
                & (scored["policy"] == pol)
                & (scored["state"] == "COMMIT")
            ].sort_values("k")
            if not len(g):
                clouds.append((f"{pol}: no commit", None, colour, math.nan))
                continue
            row = g.iloc[0]
            r, k, sub = _row_of(data, row)
            anchor = np.array([row["x"], row["y"], np.deg2rad(row["yaw_deg"])])
            pts = figures.place_submap(
                np.asarray(data.batch.submaps.points)[sub],
                np.asarray(data.batch.submaps.mask)[sub],
                anchor,
                np.asarray(data.batch.submaps.X)[sub],
            )
            label = f"{pol} k={k} room {row['room']}"
            clouds.append((label, pts, colour, row["err_xy"]))
            if pol == "ours" or truth_xy is None:
                truth_xy = data.true_pose(r, k)[:2]
        panels.append(
            {
                "title": f"three_rooms {traj}, d_s={ds:g} m: submap at each policy's "
                f"commit, placed by its anchor",
                "clouds": clouds,
                "truth_xy": truth_xy if truth_xy is not None else (np.nan, np.nan),
            }
        )
    fig = figures.commit_clouds(panels, scene.floorplan)
    return figures.save(fig, out / "commit_clouds.png")


def _anchor_space(scored, data, cands, out, ds):
    from mfcl_jax import se2

    traj = sorted(scored["trajectory"].unique())[0]
    g = scored[(scored["trajectory"] == traj) & (scored["policy"] == "ours")].sort_values("k")
    r = int(g["run"].iloc[0])
    subs = np.asarray(data.batch.runs.submap)[r]
    subs = subs[subs >= 0]
    pose, score, mask = (np.asarray(a)[subs] for a in (cands.pose, cands.score, cands.mask))
    X = np.asarray(data.batch.submaps.X)[subs]
    H = np.asarray(se2.anchor(pose, X[:, None, :]))
    top = np.argmax(np.where(mask, score, -np.inf), axis=1)
    has = mask.any(1)
    top1 = H[np.arange(len(subs)), top][has]
    com = g[g["state"] == "COMMIT"]
    t_star = (
        np.array([com["x"].iloc[0], com["y"].iloc[0], np.deg2rad(com["yaw_deg"].iloc[0])])
        if len(com)
        else None
    )
    fig = figures.anchor_space(
        H[mask],
        score[mask],
        top1,
        data.true_anchor(r),
        t_star,
        f"three_rooms {traj}, d_s={ds:g} m: anchors H = Y X^-1",
    )
    return figures.save(fig, out / "anchor_space.png")
