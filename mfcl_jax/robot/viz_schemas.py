"""Foxglove's JSON schemas of the messages ``mfcl localize --viz`` writes (``robot.viz``).

Written for Foxglove's JSON-schema parser (``@foxglove/mcap-support``'s ``parseJsonSchema``):
every property has a ``"type"`` (or a ``oneOf`` of numeric constants), arrays name their
item type, byte fields are base64 strings (``"contentEncoding": "base64"``). Only the fields
that ``robot.viz`` writes are listed; the names follow Foxglove's schemas.
"""

from __future__ import annotations

__all__ = ["SCHEMAS"]

_N, _I, _S, _B = ({"type": t} for t in ("number", "integer", "string", "boolean"))


def _obj(title: str | None = None, **props) -> dict:
    return {"type": "object", "properties": props} | ({"title": title} if title else {})


def _arr(item: dict) -> dict:
    return {"type": "array", "items": item}


def _enum(title: str, *names: str) -> dict:
    return {"title": title, "oneOf": [{"title": n, "const": i} for i, n in enumerate(names)]}


_TIME = _obj("time", sec=_I, nsec=_I)
_POSE = _obj(
    "foxglove.Pose",
    position=_obj("foxglove.Vector3", x=_N, y=_N, z=_N),
    orientation=_obj("foxglove.Quaternion", x=_N, y=_N, z=_N, w=_N),
)
_COLOR = _obj("foxglove.Color", r=_N, g=_N, b=_N, a=_N)
_LINE = _obj(
    "foxglove.LinePrimitive",
    type=_enum("foxglove.LineType", "LINE_STRIP", "LINE_LOOP", "LINE_LIST"),
    pose=_POSE,
    thickness=_N,
    scale_invariant=_B,
    points=_arr(_obj("foxglove.Point3", x=_N, y=_N, z=_N)),
    color=_COLOR,
    colors=_arr(_COLOR),
    indices=_arr(_I),
)
_TEXT = _obj(
    "foxglove.TextPrimitive",
    pose=_POSE,
    billboard=_B,
    font_size=_N,
    scale_invariant=_B,
    color=_COLOR,
    text=_S,
)
_ENTITY = _obj(
    "foxglove.SceneEntity",
    timestamp=_TIME,
    frame_id=_S,
    id=_S,
    lifetime=_obj("duration", sec=_I, nsec=_I),
    frame_locked=_B,
    metadata=_arr(_obj("foxglove.KeyValuePair", key=_S, value=_S)),
    lines=_arr(_LINE),
    texts=_arr(_TEXT),
)
_XYYAW = _obj(None, x=_N, y=_N, yaw_deg=_N)
SCHEMAS = {
    "foxglove.SceneUpdate": _obj(
        "foxglove.SceneUpdate",
        deletions=_arr(
            _obj(
                "foxglove.SceneEntityDeletion",
                timestamp=_TIME,
                id=_S,
                type=_enum("foxglove.SceneEntityDeletionType", "MATCHING_ID", "ALL"),
            )
        ),
        entities=_arr(_ENTITY),
    ),
    "foxglove.PointCloud": _obj(
        "foxglove.PointCloud",
        timestamp=_TIME,
        frame_id=_S,
        pose=_POSE,
        point_stride=_I,
        fields=_arr(
            _obj(
                "foxglove.PackedElementField",
                name=_S,
                offset=_I,
                type=_enum(
                    "foxglove.NumericType",
                    "UNKNOWN",
                    "UINT8",
                    "INT8",
                    "UINT16",
                    "INT16",
                    "UINT32",
                    "INT32",
                    "FLOAT32",
                    "FLOAT64",
                ),
            )
        ),
        data={"type": "string", "contentEncoding": "base64"},
    ),
    "foxglove.PosesInFrame": _obj(
        "foxglove.PosesInFrame", timestamp=_TIME, frame_id=_S, poses=_arr(_POSE)
    ),
    "foxglove.Log": _obj(
        "foxglove.Log",
        timestamp=_TIME,
        level=_enum("foxglove.LogLevel", "UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL"),
        message=_S,
        name=_S,
        file=_S,
        line=_I,
    ),
    # The decisions-file line (mfcl_jax.io.decisions); null values are allowed at run time.
    "mfcl.Decision": _obj(
        "mfcl.Decision",
        k=_I,
        t=_N,
        state=_S,
        anchor=_XYYAW,
        symmetry=_S,
        tau=_arr(_N),
        B1=_I,
        B2=_I,
        margin=_I,
        pose=_XYYAW,
        reason=_S,
        alternatives=_arr(_XYYAW),
    ),
}
