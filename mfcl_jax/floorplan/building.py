"""Every storey of a building as one plan (``storeys.stack_storeys``), from each format:

* IFC: every storey whose cut meets walls and spaces (``storey`` names one instead);
* GeoJSON: features carrying a ``level`` property (as indoor GeoJSON exports do) are split by
  level, one storey per level (``storey`` selects one); a file without levels is one storey;
* ROS maps (or any plans): several files, one storey each, named by the file's stem.

A building with one usable storey is that storey's plan, unchanged. With ``every`` (what
``mfcl`` does), a storey named with ``storey`` does not narrow the search: every storey is
still stacked and the named one is marked given (``Storeys.given``), so the layer can say
when the scans fit another storey instead.
"""

from __future__ import annotations

import json
from pathlib import Path

from mfcl_jax.floorplan.model import Floorplan, FloorplanError
from mfcl_jax.floorplan.storeys import stack_storeys

__all__ = ["ifc_building", "geojson_building", "stack_files"]


def _stacked(path, storeys: list[tuple[str, Floorplan]], name: str, given=None) -> Floorplan:
    if len(storeys) == 1:
        return storeys[0][1]
    plan, _ = stack_storeys(storeys, name=name, source=str(path), given=given)
    return plan


def ifc_building(path, storey=None, cut_height: float = 1.0, every: bool = False) -> Floorplan:
    """The IFC model's storey ``storey`` (name or elevation), or with None (or ``every``)
    every storey whose cut meets walls and spaces, stacked (``storey`` then marked given).

    Raises:
        FloorplanError: as ``ifc.load_ifc``; no storey has walls and spaces (each storey's
            reason is listed).
    """
    from mfcl_jax.floorplan.ifc import ifc_storeys, load_ifc

    if storey is not None:
        one = load_ifc(path, storey=storey, cut_height=cut_height)  # checks the name
        if not every:
            return one
        storey = one.source.rsplit(" [", 1)[-1].rstrip("]")
    found, why = [], []
    for sname, _ in ifc_storeys(path):
        try:
            found.append((sname, load_ifc(path, storey=sname, cut_height=cut_height)))
        except FloorplanError as e:
            why.append(str(e).split(": ", 1)[-1])
    if not found:
        raise FloorplanError(f"{path}: no storey has both walls and spaces: {'; '.join(why)}")
    return _stacked(path, found, Path(path).stem, storey)


def _level_key(v):
    try:
        return (0, float(v), str(v))
    except (TypeError, ValueError):
        return (1, 0.0, str(v))


def geojson_building(path, storey=None, every: bool = False) -> Floorplan:
    """A GeoJSON plan; with ``level`` properties, its levels stacked (or the level
    ``storey``; with ``every`` all levels, ``storey`` marked given).

    Raises:
        FloorplanError: as ``geojson.load_geojson``; some features with a level and some
            without (the first without is named), ``storey`` without levels in the file, or
            an unknown level (the levels are listed).
    """
    from mfcl_jax.floorplan.geojson import floorplan_from_geojson, load_geojson

    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return load_geojson(path)  # the reader names what is wrong
    feats = data.get("features") if isinstance(data, dict) else None
    if not isinstance(feats, list):
        return load_geojson(path)
    levels = [((f.get("properties") or {}) if isinstance(f, dict) else {}).get("level")
              for f in feats]  # fmt: skip
    if all(v is None for v in levels):
        if storey is not None:
            raise FloorplanError(
                f"{path}: storey={storey!r} given, but no feature has a 'level' property"
            )
        return floorplan_from_geojson(data, source=str(path))
    if any(v is None for v in levels):
        i = levels.index(None)
        raise FloorplanError(
            f"{path}: feature #{i} has no 'level' property while others do: give every "
            "feature its level (storey)"
        )
    names = sorted({str(v) for v in levels}, key=_level_key)
    if storey is not None and str(storey) not in names:
        raise FloorplanError(f"{path}: unknown level {storey!r}; levels: {', '.join(names)}")
    chosen = [str(storey)] if storey is not None and not every else names
    storeys = []
    for lv in chosen:
        part = [f for f, v in zip(feats, levels, strict=True) if str(v) == lv]
        fp = floorplan_from_geojson(
            {**data, "features": part}, source=f"{path} [level {lv}]", name=f"{path.stem} {lv}"
        )
        storeys.append((lv, fp))
    return _stacked(path, storeys, path.stem, None if storey is None else str(storey))


def stack_files(plans: list[tuple[Path, Floorplan]], given: str | None = None) -> Floorplan:
    """Several plan files, one storey each (named by the file's stem), stacked (``given``:
    the stem of the storey the user named)."""
    names = [p.stem for p, _ in plans]
    if len(set(names)) != len(names):
        raise FloorplanError(
            f"floor plans {[str(p) for p, _ in plans]}: two share the name "
            "(file stem) that names their storey; rename one"
        )
    src = " + ".join(str(p) for p, _ in plans)
    return _stacked(src, [(p.stem, fp) for p, fp in plans], "building", given)
