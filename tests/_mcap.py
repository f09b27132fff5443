"""Reading back what ``mfcl localize --viz`` and ``VizWriter`` write, for the tests: every
message of a complete MCAP file (the MCAP library's own reader), clouds and poses decoded."""

from __future__ import annotations

import base64
import json
import math

import numpy as np
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from mfcl_jax.robot.viz import SCHEMAS, TOPICS

MAGIC = b"\x89MCAP0\r\n"


def _read(path) -> dict:
    """Every message by topic as ``(log_time, schema name, decoded JSON)``, after checking
    that the file is complete: magic at both ends, a summary whose counts match."""
    data = path.read_bytes()
    assert data.startswith(MAGIC) and data.endswith(MAGIC)
    with open(path, "rb") as f:
        assert sum(1 for _ in StreamReader(f).records) > 0  # parses to the footer
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        out: dict[str, list] = {t: [] for t in TOPICS}
        for schema, channel, msg in reader.iter_messages(log_time_order=True):
            assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
            assert json.loads(schema.data) == SCHEMAS[schema.name]
            out[channel.topic].append((msg.log_time, schema.name, json.loads(msg.data)))
    assert summary.statistics.message_count == sum(len(v) for v in out.values())
    names = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert names == TOPICS
    return out


def _cloud(msg) -> np.ndarray:
    """The points of a ``foxglove.PointCloud`` message, placed by its pose: ``(n, 2)``."""
    assert msg["point_stride"] == 8 and [f["name"] for f in msg["fields"]] == ["x", "y"]
    pts = np.frombuffer(base64.b64decode(msg["data"]), "<f4").reshape(-1, 2).astype(float)
    p, q = msg["pose"]["position"], msg["pose"]["orientation"]
    yaw = 2 * math.atan2(q["z"], q["w"])
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = pts[:, 0], pts[:, 1]
    return np.stack([p["x"] + c * x - s * y, p["y"] + s * x + c * y], 1)


def _xyyaw(pose) -> list[float]:
    p, q = pose["position"], pose["orientation"]
    return [p["x"], p["y"], math.degrees(2 * math.atan2(q["z"], q["w"]))]


def _no_leftovers(folder) -> None:
    assert not [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]
