"""The benchmark's multirun through a cluster launcher (hydra-submitit-launcher), then merged.

``submitit_local`` runs each job as a local process through the same Submitit path as
``submitit_slurm`` (pickled job, job array, results read back): two families, two jobs, the
smallest benchmark (one building, one walk, no faults, no figures), then
``experiments.merge_benchmark`` builds the tables from the jobs' folders.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd

from experiments import merge_benchmark

ROOT = Path(__file__).resolve().parents[1]


def test_submitit_multirun_of_the_benchmark_merges_into_one_table(tmp_path):
    sweep = tmp_path / "multirun"
    cmd = [sys.executable, "-m", "experiments.benchmark", "-m", "hydra/launcher=submitit_local",
           "families=plain,bays", "seeds=1", "walks=1", "faults=[]",
           "policies=[ours,single_shot]", "figures=false", "progress=false",
           f"cache={tmp_path / 'cache'}", f"hydra.sweep.dir={sweep}"]  # fmt: skip
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert list((sweep / ".submitit").iterdir()), "the jobs did not go through Submitit"
    jobs = sorted(p.parent.name for p in sweep.glob("*/runs.csv"))
    assert jobs == ["0", "1"]

    out = tmp_path / "merged"
    assert merge_benchmark.main([str(sweep), str(out)]) == 0
    for name in ("families.md", "families.csv", "overall.md", "risk_coverage.csv"):
        assert (out / name).is_file(), name
    fam = pd.read_csv(out / "families.csv")
    assert {"plain", "bays", "all"} <= set(fam["family"])
    assert set(fam["policy"]) == {"ours", "single_shot"}
    every = fam[fam["family"] == "all"].set_index("policy")["runs"]
    assert (every == 2).all()  # one run from each job, under each policy
