"""Real-data results: ``python -m experiments.real`` (logic in ``mfcl_jax.study.real``)."""

import sys

from mfcl_jax.study.real import main

if __name__ == "__main__":
    sys.exit(main())
