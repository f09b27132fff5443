"""What a decision means, for a person: the status line of a window and the states and
reasons explained (``mfcl localize --help`` and ``docs/status.md`` print the same text); the
decisions file's record of a window is ``records``.

Plain Python (no NumPy or JAX), so ``mfcl --help`` stays light.
"""

from __future__ import annotations

__all__ = [
    "STATE_TEXT",
    "REASON_TEXT",
    "TERM_TEXT",
    "help_text",
    "markdown",
    "status_line",
    "summary_table",
]

STATE_TEXT = {
    "COMMIT": "localized: one place in the building explains the scans and no symmetric "
    "copy of it stays possible; the line gives the robot's current pose in the plan frame.",
    "AMBIGUOUS": "the scans match the building, but more than one place fits them equally "
    "(a repeated layout with period tau, a rotational or mirror symmetry, several separate "
    "places: multimodal, or the same place on several storeys: storey); where a competing "
    "placement is known, the line gives the robot's pose under the best placement and under "
    "it ('robot at (x, y, heading) or (...)'); walk on towards something that tells the "
    "places apart.",
    "DEFER": "not enough evidence yet; the reason says what is missing. Keep moving.",
}

# Keys: ``decision.outcome.REASONS`` (a test keeps them in step). Value: (short phrase for a
# status line, one plain sentence for the help).
REASON_TEXT = {
    "unsaturated": (
        "too little seen yet",
        "Fewer than b_min (3) stretches of the walk that share no scan have a registration: "
        "too little of the building seen to tell similar places apart. Keep moving.",
    ),
    "winner infeasible": (
        "the best placement runs the path through walls",
        "The best placement would put the travelled path through walls or outside the rooms "
        "(its gate consistency is below tau_c), so it cannot be right.",
    ),
    "no feasible champion": (
        "every placement runs the path through walls",
        "Every window's best registration was rejected by the feasibility gate: none keeps "
        "the travelled path inside the building's free space.",
    ),
    "spread": (
        "the supporting windows disagree",
        "The windows that support the best placement disagree with each other by more than "
        "sigma_max metres: the registrations are not yet consistent.",
    ),
    "below floor": (
        "the scans match the plan poorly",
        "Every registration scores below the score floor: the scans do not match this floor "
        "plan well (wrong plan or storey, or a 3-D cloud sliced at the wrong height?).",
    ),
    "no anchors": (
        "no registration found yet",
        "The front-end found no candidate placement for any window yet (too few points, or "
        "no straight wall seen in the scans so far).",
    ),
    "alias without period": (
        "a shifted copy fits, with no period",
        "A shifted copy of the best placement fits the scans as well, but no single period "
        "of the building explains the shift, so no tau can be given.",
    ),
    "not triggered": (
        "the baseline has not fired",
        "A baseline policy's commit rule has not fired yet (baselines only; mfcl localize "
        "runs the selective policy).",
    ),
    "commit contradicted": (
        "another place became decisive",
        "The layer had committed, but another placement, more than the grouping tolerance "
        "away, has since become decisive: the commit is withdrawn (AMBIGUOUS) and the next "
        "windows decide afresh.",
    ),
    "commit infeasible": (
        "the committed placement runs the path through walls",
        "The layer had committed, but the tracked placement now puts the travelled path "
        "through walls or out of the building: the commit is withdrawn (DEFER).",
    ),
    "commit stale": (
        "the newest scans place the robot off the committed pose",
        "The layer had committed, but the newest window's best registration puts the robot "
        "at the same place yet farther than the tracking tolerance (0.5 m or 3 deg) from "
        "where the commit does: the odometry drifted faster than the commit could follow, "
        "so the commit is withdrawn (DEFER) and the next windows decide afresh.",
    ),
    "commit drifted": (
        "the newest scan fits the plan off the commit's heading",
        "The layer reports a commit only where the window's last scan, fitted to the plan "
        "from the committed pose, stays within the tracking tolerance (3 deg) of its "
        "heading: here the fit turned farther, so the odometry has turned the pose off what "
        "the scan says (drift, or odometry that arrives late at a turn). The commit is "
        "withdrawn (DEFER) and the next windows decide afresh.",
    ),
    "commit unsupported": (
        "the newest scan touches no wall near the committed pose",
        "The layer reports a commit only where the window's last scan touches "
        "the plan's walls near the committed pose: here they touch none, so the robot is in "
        "a stretch the plan does not show (or the pose is far off) and the pose rests on "
        "odometry alone. The commit is withdrawn (DEFER) and the next windows decide afresh.",
    ),
    "competitor not ruled out": (
        "another placement fits the scans as well",
        "The best placement is decisive by consensus, but re-scoring the windows' scans "
        "under a competing placement (a symmetric copy, another group, a window's runner-up) "
        "finds no window that contradicts it: both explain what the robot saw.",
    ),
    "winner contradicted": (
        "the scans favour another placement",
        "Re-scoring the windows' scans favours a competing placement over the best one in "
        "some window and never the other way: the consensus winner is not trusted.",
    ),
    "other storey": (
        "the scans fit another storey than the one given",
        "With --storey on a plan of several storeys every storey is still weighed: the layer "
        "would commit, but on another storey (storeys names it) than the one given, so the "
        "robot is probably not where you said; no pose is given. Check the storey, or leave "
        "--storey out and let the layer name it.",
    ),
}

TERM_TEXT = {
    "pose": "COMMIT lines: the robot's current pose in the plan frame, T* X_k (x, y in "
    "metres, heading in degrees counter-clockwise from the plan's x axis).",
    "storey": "with a plan of several storeys (an IFC model without --storey, GeoJSON "
    "levels, several --floorplan maps): COMMIT names the storey and gives the pose in its "
    "frame; AMBIGUOUS storey lists the storeys where the same place fits (congruent floors: "
    "walk on to something that differs between them, or name the storey with --storey).",
    "B1": "support of the best placement: how many windows that share no scan have their "
    "best registration agree with it (independent evidence for it).",
    "B2": "support of the runner-up, a different placement, counted the same way (the "
    "evidence against); at a window that could commit, the layer re-scores the scans under "
    "every competitor and a placement they contradict is not counted.",
    "margin": "B1 - B2. A COMMIT needs B1 >= b_min (3) and margin >= delta_min (2); then "
    "every competing placement (symmetric copies, other groups, each window's runner-up) must "
    "be contradicted by the scans of some window and favoured by none.",
    "tau": "the period (tx, ty in metres) of a repeated layout: the robot's position is known "
    "only up to whole multiples of tau (AMBIGUOUS translation).",
    "L": "with --early-commit only: the uniqueness test's log-likelihood ratio of the whole "
    "path so far, its best placement against the best one more than 1 m / 5 deg from it, as "
    "L=ratio/threshold (threshold log(1/alpha)); the layer also commits once the ratio reaches "
    "the threshold and the gate, the newest window's best registration and the consensus do "
    "not object (L=vetoed where one did). L=- where the test did not run at that window "
    "(it runs where the newest window has a best registration that a consensus of two or "
    "more windows does not contradict, at most 8 times per odometry segment; after that only "
    "the count of windows commits). With --early-commit grid: the evidence grid's margin, "
    "its best placement against the best other one (threshold 4 nats; read at every window).",
}

EXAMPLE = (
    "k=  1 t=     12.00 DEFER     unsaturated (too little seen yet)  [B1=1 B2=0 margin=1]",
    "k=  3 t=     20.00 AMBIGUOUS repeated layout: position known up to multiples of "
    "tau=(7.30, 0.00) m  [B1=3 B2=0 margin=3]",
    "k= 11 t=     48.00 COMMIT    robot at x=21.40 m, y=6.02 m, heading 87.5 deg  "
    "[B1=9 B2=1 margin=8]",
)

_KINDS = {
    "storey": "the same place on several storeys",
    "translation": "repeated layout",
    "rotation": "rotational symmetry",
    "mirror": "mirror symmetry",
    "multimodal": "several separate places fit",
}


def _wrap(text: str, indent: str, width: int = 88) -> str:
    import textwrap

    return textwrap.fill(text, width, initial_indent=indent, subsequent_indent=indent + "  ")


def help_text() -> str:
    """The states, reasons and terms as plain text (the ``mfcl localize`` epilog)."""
    out = ["status lines (one per window):"]
    out += [_wrap(f"{s}: {t}", "  ") for s, t in STATE_TEXT.items()]
    out += ["", "reasons (DEFER, and AMBIGUOUS without a symmetry):"]
    out += [_wrap(f"{r}: {t}", "  ") for r, (_, t) in REASON_TEXT.items()]
    out += ["", "numbers:"]
    out += [_wrap(f"{n}: {t}", "  ") for n, t in TERM_TEXT.items()]
    return "\n".join(out)


def markdown() -> str:
    """The same text as a Markdown snippet (``docs/status.md``)."""
    out = [
        "## Reading `mfcl localize` status lines",
        "",
        "One line per window, for example:",
        "",
        "```",
        *EXAMPLE,
        "```",
        "",
        "States:",
        "",
    ]
    out += [f"- **{s}**: {t}" for s, t in STATE_TEXT.items()]
    out += ["", "Reasons (DEFER, and AMBIGUOUS without a symmetry):", ""]
    out += [f"- `{r}`: {t}" for r, (_, t) in REASON_TEXT.items()]
    out += ["", "Numbers:", ""]
    out += [f"- **{n}**: {t}" for n, t in TERM_TEXT.items()]
    out += [
        "",
        "The decisions file (`--out`, JSON lines) holds the same per line: `k` (the window, "
        "counted over the whole recording), `segment` (the odometry segment: 0, plus one "
        "after every odometry jump, where the layer starts over), `t, state, "
        "anchor, symmetry, tau, B1, B2, margin`, plus `pose` (`{x, y, yaw_deg}` "
        'of the robot in the plan frame when COMMIT, else `null`), `reason` (`""` when '
        "none) and `alternatives` (when AMBIGUOUS: a list of the robot's poses `{x, y, "
        "yaw_deg}` in the plan frame, one per explanation the layer could not tell apart, "
        "the best placement first, then the strongest competitor; `null` for other states). "
        "With `--early-commit` every line also holds `unique`: `{llr, needed}`, the "
        'uniqueness test\'s ratio at that window (`null` where it did not run, `"inf"` '
        'where no other placement was found; `"-inf"` where a veto held) and the ratio a '
        "commit needs. With a plan of several storeys every line also holds `storey` (the "
        "storey's name when COMMIT, else `null`) and `storeys` (the storeys still possible: "
        "the commit's, or those of the explanations of an AMBIGUOUS window; `null` for "
        "DEFER); the anchor, pose and alternatives are in that storey's frame, and each "
        "alternative names its `storey`.",
    ]
    return "\n".join(out) + "\n"


def _places(d: dict) -> str:
    """``"; robot at (x, y, h) or (x, y, h)"``: where the explanations an AMBIGUOUS record
    lists place the robot (empty when it lists fewer than two)."""
    alt = d.get("alternatives") or []
    if len(alt) < 2:
        return ""
    return "; robot at " + " or ".join(
        f"({a['x']:.2f}, {a['y']:.2f}, {a['yaw_deg']:.0f} deg"
        + (f" on {a['storey']!r})" if a.get("storey") else ")")
        for a in alt
    )


def status_line(d: dict, detail: str = "") -> str:
    """One line for a person from a decisions-file record (``record``'s keys); a window
    after an odometry jump shows its ``segment``."""
    head = f"k={d['k']:3d} t={d['t']:10.2f} {d['state']:9s}"
    if d["state"] == "COMMIT":
        p = d["pose"]
        on = f" on storey {d['storey']!r}" if d.get("storey") else ""
        what = f"robot{on} at x={p['x']:.2f} m, y={p['y']:.2f} m, heading {p['yaw_deg']:.1f} deg"
    elif d["symmetry"] == "storey":
        names = ", ".join(repr(n) for n in d.get("storeys") or [])
        what = f"storey unknown: the same place on storeys {names}" + _places(d)
    elif d["symmetry"] == "translation" and d["tau"] is not None:
        tx, ty = d["tau"]
        what = f"repeated layout: position known up to multiples of tau=({tx:.2f}, {ty:.2f}) m"
        what += _places(d)
    elif d["symmetry"] in _KINDS:
        what = _KINDS[d["symmetry"]] + _places(d)
    elif d.get("reason"):
        short = REASON_TEXT.get(d["reason"], (d["reason"],))[0]
        what = f"{d['reason']} ({short})"
    else:
        what = "one candidate place; too few agreeing windows yet"
    tail = f"B1={d['B1']} B2={d['B2']} margin={d['margin']}"
    if d.get("unique"):  # --early-commit: the uniqueness test's ratio against its threshold
        u = d["unique"]
        v = u["llr"]
        ratio = {None: "-", "-inf": "vetoed"}.get(v, v) if not isinstance(v, float) else f"{v:.2f}"
        tail += f" L={ratio}/{u['needed']:.2f}"
    if d.get("segment"):  # after an odometry jump (segment 0 is not shown)
        tail += f" segment={d['segment']}"
    tail += f" {detail}" if detail else ""
    return f"{head} {what}  [{tail}]"


def summary_table(rows) -> str:
    """A plain-text table of per-dataset summaries.

    Args:
        rows: dicts with ``dataset``, ``windows``, ``first_commit`` (k or None) and
            ``final_state`` (or None when there is no window).
    """
    head = ("dataset", "windows", "first commit k", "final state")
    body = [
        (
            str(r["dataset"]),
            str(r["windows"]),
            "-" if r["first_commit"] is None else str(r["first_commit"]),
            r["final_state"] or "-",
        )
        for r in rows
    ]
    width = [max(len(c) for c in col) for col in zip(head, *body, strict=True)]
    fmt = "  ".join(f"{{:<{w}}}" for w in width)
    lines = [fmt.format(*head), fmt.format(*("-" * w for w in width))]
    return "\n".join(line.rstrip() for line in lines + [fmt.format(*b) for b in body])
