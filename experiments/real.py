"""Real-data results: ``python -m experiments.real`` (logic in ``mfcl_jax.study.real``).
A full run into the default ``results/real`` refreshes the README's generated real-data block."""

import sys

from mfcl_jax.study.readme import update_docs
from mfcl_jax.study.real import main

if __name__ == "__main__":
    rc = main()
    if not rc and not any(a.startswith("--out") or a == "--quick" for a in sys.argv[1:]):
        names = update_docs("results")
        print(f"README and docs: refreshed {len(names)} generated tables")
    sys.exit(rc)
