"""The benchmark's multirun through a cluster launcher (hydra-submitit-launcher), then merged.

``submitit_local`` runs each job as a local process through the same Submitit path as
``submitit_slurm`` (pickled job, job array, results read back). The two jobs are
``test_benchmark.py``'s small benchmark without the particle filter, at two window lengths
``d_s``: the same compiled programs as that file's benchmark (the suite's disk cache hands them
to the jobs, which otherwise compile the front-end and the layer side by side, about 35 s of
CPU each). ``experiments.merge_benchmark`` then refuses to make one table of the two (runs of
different ``d_s`` are two benchmarks) and builds the tables of each job's folder alone.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd

from experiments import merge_benchmark

ROOT = Path(__file__).resolve().parents[1]


def test_submitit_multirun_of_the_benchmark_runs_each_job_and_merges_one_d_s_at_a_time(
    tmp_path, capsys
):
    sweep = tmp_path / "multirun"
    cmd = [sys.executable, "-m", "experiments.benchmark", "-m", "hydra/launcher=submitit_local",
           "families=[bays]", "seeds=1", "walks=1", "faults=[restart]", "fault_seeds=1",
           "policies=[ours,paper,single_shot,gate_only]", "d_s=6,7", "figures=false",
           "progress=false", f"cache={tmp_path / 'cache'}", f"hydra.sweep.dir={sweep}"]  # fmt: skip
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert list((sweep / ".submitit").iterdir()), "the jobs did not go through Submitit"
    jobs = sorted(p.parent.name for p in sweep.glob("*/runs.csv"))
    assert jobs == ["0", "1"]
    d_s = {j: set(pd.read_csv(sweep / j / "runs.csv")["d_s"]) for j in jobs}
    assert sorted(map(tuple, d_s.values())) == [(6.0,), (7.0,)]

    capsys.readouterr()
    assert merge_benchmark.main([str(sweep), str(tmp_path / "mixed")]) == 1
    err = capsys.readouterr().err
    assert "different window lengths" in err and "d_s=6" in err and "d_s=7" in err, err
    assert not (tmp_path / "mixed").exists()  # nothing half-written

    for j in jobs:
        one = tmp_path / "one" / j
        one.mkdir(parents=True)
        (one / "0").symlink_to(sweep / j)
        assert merge_benchmark.main([str(one), str(tmp_path / f"merged{j}")]) == 0
        fam = pd.read_csv(tmp_path / f"merged{j}" / "families.csv")
        assert set(fam["policy"]) == {"ours", "paper", "single_shot", "gate_only"}
        assert (fam.loc[fam["family"] == "all", "runs"] == 1).all()  # the job's one walk
        assert (tmp_path / f"merged{j}" / "faults" / "restart.md").is_file()
