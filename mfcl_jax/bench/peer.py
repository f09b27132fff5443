"""The particle-filter peer in the benchmark: the same scans and odometry, decisions in the
decision table's format.

The filter (``peers.mcl``) runs once per group of recordings over the keyframes our layer
uses; at every window end a robot running it would report its pose once the cloud has
converged (``peers.mcl.commits``: position spread <= ``commit_xy`` and heading spread <= 10
deg). Converged windows are COMMIT with the filter's anchor ``pose X^-1`` (it keeps reporting
its current estimate, so a later wrong estimate is a false commit like any other); the others
DEFER. The knob of the risk-coverage sweep is ``commit_xy``, one value per threshold set.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["COMMIT_XY", "make_mcl_runner"]

# commit_xy (m) of each threshold set, aligned with ``bench.run.KNOB_SETS`` (set 1: default)
COMMIT_XY = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)


def make_mcl_runner(cfg, seed: int = 0):
    """``runner(recordings, windows, run_offset) -> DataFrame`` rows of policy ``mcl``."""
    from mfcl_jax.peers import MCLParams, commits, pad_batch, prepare_mcl_inputs, run_mcl

    params = MCLParams(n_particles=int(cfg.mcl_particles))

    def runner(recs, wins, run_offset: int) -> pd.DataFrame:
        keep = [i for i, w in enumerate(wins) if len(w)]
        if not keep:
            return pd.DataFrame()
        batch = prepare_mcl_inputs(
            [recs[i] for i in keep],
            [wins[i].bounds[:, 1] for i in keep],
            [wins[i].keyframes for i in keep],
            max_points=params.n_beams,
        )
        # coarse buckets: every group of the benchmark shares a few compilations; the padded
        # runs (copies) are never read
        tr = run_mcl(pad_batch(batch, grid=256), params, seeds=(seed,))
        rows = []
        for s, xy in enumerate(COMMIT_XY):
            ok = commits(tr, commit_xy=xy)[:, 0]  # (R, K)
            for j, i in enumerate(keep):
                n = len(wins[i])
                a = tr.anchor[j, 0, :n]
                rows.append(
                    pd.DataFrame(
                        dict(
                            run=run_offset + i,
                            k=np.arange(1, n + 1),
                            set=s,
                            policy="mcl",
                            state=np.where(ok[j, :n], "COMMIT", "DEFER"),
                            kind=None,
                            x=a[:, 0],
                            y=a[:, 1],
                            yaw_deg=np.rad2deg(a[:, 2]),
                            reason=np.where(ok[j, :n], "", "not converged"),
                            knob=f"commit_xy={xy}",
                        )
                    )
                )
        return pd.concat(rows, ignore_index=True)

    return runner
