"""The study: ``python -m experiments.sweep d_s=5,6,7`` regenerates every table and figure.

Without ``-m`` a comma list (``d_s=5,6,7``, ``scenes=a,b``) is batched in ONE process: the
entry point rewrites it to a list before Hydra sees it. With ``-m`` Hydra launches one job per
value (basic or joblib launcher) and ``python -m experiments.merge multirun/<date>/<time>``
builds the same tables from the jobs' outputs.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import hydra
from omegaconf import DictConfig

from mfcl_jax.config import register_configs, to_study

LIST_KEYS = ("d_s", "scenes")


def batch_comma_lists(argv: list[str]) -> list[str]:
    """Rewrites ``key=a,b,c`` to ``key=[a,b,c]`` for list keys unless Hydra runs a multirun."""
    # ``scene=x`` is accepted as the singular of ``scenes``.
    argv = [re.sub(r"^(\+?)scene=", r"\1scenes=", a) for a in argv]
    if any(a in ("-m", "--multirun") for a in argv):
        return argv
    out = []
    for a in argv:
        m = re.fullmatch(r"(\+?)({})=([^\[\]]*,[^\[\]]*)".format("|".join(LIST_KEYS)), a)
        out.append(f"{m.group(1)}{m.group(2)}=[{m.group(3)}]" if m else a)
    return out


register_configs()


@hydra.main(config_path="../conf", config_name="sweep", version_base="1.3")
def main(cfg: DictConfig) -> None:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from mfcl_jax.study.run import run_study

    study = to_study(cfg)
    if HydraConfig.get().mode == RunMode.MULTIRUN:
        # Each job writes its raw outputs to its own folder; experiments.merge joins them.
        study.out = HydraConfig.get().runtime.output_dir
    tabs = run_study(study)
    print(f"wrote {len(tabs)} tables to {study.out}/")
    if Path(study.out).resolve() == Path("results").resolve():
        from mfcl_jax.study.readme import update_docs

        names = update_docs(study.out)
        print(f"README and docs: refreshed {len(names)} generated tables")


if __name__ == "__main__":
    sys.argv = batch_comma_lists(sys.argv)
    main()
