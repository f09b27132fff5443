"""Real-data results: ``python -m experiments.real`` (logic in ``mfcl_jax.pipeline.real``)."""

import sys

from mfcl_jax.pipeline.real import main

if __name__ == "__main__":
    sys.exit(main())
