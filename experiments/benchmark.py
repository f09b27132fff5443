"""The generalisation benchmark: ``python -m experiments.benchmark`` (Hydra).

Without ``-m`` a comma list (``families=plain,bays``, ``policies=ours,mcl``, ``faults=drift,
clutter``) is batched in ONE process. With ``-m`` Hydra launches one job per value (basic,
joblib, or Submitit: ``hydra/launcher=slurm`` for a SLURM job array, ``conf/hydra/launcher``;
``submitit_local`` for local processes), each writing its ``runs.csv`` into its job folder, and
``python -m experiments.merge_benchmark multirun/benchmark/<date>/<time>`` builds the same
tables from them. Split by ``families``: every job then runs different recordings.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import hydra
from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf

from mfcl_jax.bench.config import BenchmarkConfig

LIST_KEYS = ("families", "policies", "faults")

ConfigStore.instance().store(name="benchmark_schema", node=BenchmarkConfig)


def batch_comma_lists(argv: list[str]) -> list[str]:
    """Rewrites ``key=a,b`` for list keys: to ``key=[a,b]`` (one batched process), or under a
    multirun to ``key=[a],[b]`` (one job per value; the schema takes lists only)."""
    multi = any(a in ("-m", "--multirun") for a in argv)
    out = []
    for a in argv:
        m = re.fullmatch(r"({})=([^\[\]]*)".format("|".join(LIST_KEYS)), a)
        if not m:
            out.append(a)
        elif multi:
            out.append(f"{m.group(1)}=" + ",".join(f"[{v}]" for v in m.group(2).split(",")))
        else:
            out.append(f"{m.group(1)}=[{m.group(2)}]")
    return out


@hydra.main(config_path="../conf", config_name="benchmark", version_base="1.3")
def main(cfg: DictConfig) -> None:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from mfcl_jax.bench.config import BenchmarkError
    from mfcl_jax.bench.main import run_benchmark

    d = OmegaConf.to_container(cfg, resolve=True)
    for k in LIST_KEYS:
        if not isinstance(d[k], list):
            d[k] = [d[k]]
    bench = BenchmarkConfig(**d)
    if HydraConfig.get().mode == RunMode.MULTIRUN:
        bench.out = HydraConfig.get().runtime.output_dir
    try:
        tabs = run_benchmark(bench)
    except BenchmarkError as e:
        print(f"benchmark: error: {e}", file=sys.stderr)
        sys.exit(2)
    print(f"wrote {len(tabs)} tables to {bench.out}/")
    # the committed outputs (results/benchmark, results/benchmark_large) feed README tables
    if Path(bench.out).resolve().parent == Path("results").resolve():
        from mfcl_jax.study.readme import update_docs

        names = update_docs("results")
        print(f"README and docs: refreshed {len(names)} generated tables")


if __name__ == "__main__":
    sys.argv = batch_comma_lists(sys.argv)
    main()
