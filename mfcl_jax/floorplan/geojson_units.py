"""Units of a GeoJSON floor plan: metres expected; degrees refused; millimetres converted
when declared, refused when only guessed.

Rules (checked on the whole FeatureCollection before any feature is read):

1. Declared units: a collection-level ``"units"`` member (or ``properties.units``) of
   ``m``/``metre``/``meter`` (scale 1), ``cm`` (0.01) or ``mm`` (0.001): coordinates and wall
   ``thickness`` values are multiplied by the scale. Any other value is an error.
2. A ``crs`` member naming a geographic CRS (EPSG:4326, EPSG:4258, OGC CRS84) is refused:
   its coordinates are longitude/latitude degrees, not metres. No conversion is attempted;
   the message asks for a projected (metric) export.
3. Without declared units, coordinates that all lie within [-180, 180] x [-90, 90] with a
   plan extent under 0.05 units are taken as degrees (a building of 5 cm is no building)
   and refused.
4. Without declared units, an extent over 2,000 units together with wall thicknesses over
   20 units or a median room side (square root of its area) over 100 units is taken as
   millimetres and refused with a message naming millimetres and the ``"units": "mm"``
   declaration that converts it.
"""

from __future__ import annotations

import numpy as np

from mfcl_jax.floorplan.model import FloorplanError

__all__ = ["metre_scale", "scaled"]

_SCALES = {
    "m": 1.0,
    "metre": 1.0,
    "metres": 1.0,
    "meter": 1.0,
    "meters": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "millimetre": 0.001,
    "millimetres": 0.001,
    "millimeter": 0.001,
    "millimeters": 0.001,
}
_GEOGRAPHIC = ("EPSG:4326", "EPSG::4326", "EPSG:4258", "EPSG::4258", "CRS84")


def _numbers(coords) -> list[np.ndarray]:
    """Every position ``(2,)`` in a nested coordinate list (malformed parts are skipped: the
    feature reader reports them with their feature index)."""
    out = []
    stack = [coords]
    while stack:
        c = stack.pop()
        if isinstance(c, list | tuple):
            if len(c) >= 2 and all(isinstance(v, int | float) for v in c[:2]):
                out.append(np.asarray(c[:2], float))
            else:
                stack.extend(c)
    return out


def _ring_area(ring) -> float:
    try:
        xy = np.asarray(ring, float)[:, :2]
    except (TypeError, ValueError, IndexError):
        return 0.0
    x, y = xy[:, 0], xy[:, 1]
    return abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))) / 2.0


def metre_scale(data: dict, source: str) -> float:
    """The factor that turns the collection's coordinates into metres (module rules).

    Raises:
        FloorplanError: geographic degrees (declared or recognised), guessed millimetres, or
            an unknown ``units`` value; each names the unit problem and the values seen.
    """
    units = data.get("units", (data.get("properties") or {}).get("units"))
    crs = data.get("crs")
    crs_props = (crs.get("properties") or {}) if isinstance(crs, dict) else {}
    crs_name = str(crs_props.get("name", "")) if isinstance(crs_props, dict) else ""
    if any(tag in crs_name.upper() for tag in _GEOGRAPHIC):
        raise FloorplanError(
            f"{source}: crs {crs_name!r} is longitude/latitude in degrees, not metres; "
            "export the plan in a projected (metric) CRS such as UTM, or in local metres"
        )
    if units is not None:
        key = str(units).strip().lower()
        if key not in _SCALES:
            raise FloorplanError(f"{source}: units={units!r} is not known; use one of m, cm, mm")
        return _SCALES[key]
    feats = data.get("features") if isinstance(data.get("features"), list) else []
    pts, thick, areas = [], [], []
    for f in feats:
        if not isinstance(f, dict):
            continue
        geom = f.get("geometry") or {}
        props = f.get("properties") or {}
        pts.extend(_numbers(geom.get("coordinates")))
        t = props.get("thickness")
        if isinstance(t, int | float):
            thick.append(float(t))
        if geom.get("type") == "Polygon" and props.get("kind", "room") == "room":
            rings = geom.get("coordinates") or [[]]
            areas.append(_ring_area(rings[0]))
    if not pts:
        return 1.0
    xy = np.asarray(pts)
    lo, hi = xy.min(0), xy.max(0)
    ext = hi - lo
    if (
        np.all(np.abs(xy[:, 0]) <= 180)
        and np.all(np.abs(xy[:, 1]) <= 90)
        and float(ext.max()) < 0.05
    ):
        raise FloorplanError(
            f"{source}: coordinates look like longitude/latitude degrees, not metres (all "
            f"within [-180, 180] x [-90, 90], extent {ext[0]:.3g} x {ext[1]:.3g} units); "
            "export the plan in a projected (metric) CRS or local metres"
        )
    side = float(np.median(np.sqrt(areas))) if areas else 0.0
    t_max = max(thick) if thick else 0.0
    if float(ext.max()) > 2000 and (t_max > 20 or side > 100):
        raise FloorplanError(
            f"{source}: coordinates look like millimetres, not metres (extent "
            f"{ext[0]:.0f} x {ext[1]:.0f} units, wall thickness up to {t_max:g}, median room "
            f'side {side:.0f}); add "units": "mm" to the FeatureCollection to convert, '
            "or export in metres"
        )
    return 1.0


def _scale_coords(c, k: float):
    if isinstance(c, list | tuple):
        return [_scale_coords(v, k) for v in c]
    if isinstance(c, int | float) and not isinstance(c, bool):
        return c * k
    return c


def scaled(data: dict, k: float) -> dict:
    """A copy of the collection with coordinates and wall thicknesses multiplied by ``k``."""
    if k == 1.0:
        return data
    feats = []
    for f in data.get("features") or []:
        if not isinstance(f, dict):
            feats.append(f)
            continue
        f = dict(f)
        if isinstance(f.get("geometry"), dict):
            g = dict(f["geometry"])
            g["coordinates"] = _scale_coords(g.get("coordinates"), k)
            f["geometry"] = g
        props = f.get("properties")
        if isinstance(props, dict) and isinstance(props.get("thickness"), int | float):
            f["properties"] = dict(props, thickness=props["thickness"] * k)
        feats.append(f)
    return dict(data, features=feats)
