"""Where the real data lives (laser logs, the Intel bag, IFC models, ROS maps): read there,
never copied into the repository.

``MFCL_DATA`` names the folder; unset, it is ``shared/data`` beside the repository checkout
(``../shared/data`` from the repository root), where the project's data is kept. Every
module, benchmark and test asks ``data_dir()``; code that needs the data skips or says so
when the folder is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["data_dir", "ENV"]

ENV = "MFCL_DATA"
_CHECKOUT = Path(__file__).resolve().parents[2]  # the repository root (a source checkout)


def data_dir() -> Path:
    """The data folder (``MFCL_DATA``, else ``<checkout>/../shared/data``); it may be absent."""
    env = os.environ.get(ENV, "").strip()
    if env:
        return Path(env).expanduser().resolve()
    return (_CHECKOUT.parent / "shared" / "data").resolve()
