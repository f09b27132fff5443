"""One entry point for every floor-plan file format.

Every plan is read in float64 and then, when it lies far from the origin (a georeferenced
plan), moved next to it with the shift recorded in ``Floorplan.offset``
(``mfcl_jax.floorplan.origin``), so that no float32 raster or kernel sees large coordinates.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from mfcl_jax.floorplan.model import Floorplan, FloorplanError, FloorplanWarning

__all__ = ["load_floorplan", "load_building", "floorplan_files", "FLOORPLAN_SUFFIXES"]

FLOORPLAN_SUFFIXES = (".geojson", ".json", ".ifc", ".yaml", ".yml")


def load_floorplan(
    path,
    storey=None,
    cut_height: float = 1.0,
    free_thresh: float | None = None,
    occupied_thresh: float | None = None,
    local: bool = True,
    every: bool = False,
) -> Floorplan:
    """Loads a floor plan, choosing the reader by the file extension.

    Args:
        path: ``.geojson``/``.json`` (GeoJSON), ``.ifc`` (IFC model), ``.yaml``/``.yml``
            (ROS map_server map).
        storey: IFC storey name or elevation, or GeoJSON level; None: every storey (IFC:
            those whose cut meets walls and spaces; GeoJSON: every ``level``), laid side by
            side in one plan when there are several (``storeys.stack_storeys``).
        cut_height: IFC cutting-plane height above the storey (m).
        free_thresh, occupied_thresh: override the ROS map's thresholds (ROS maps only).
        local: move a plan far from the origin next to it (``origin.local_origin``).
        every: with ``storey``, still stack every storey and mark that one given
            (``storeys.Storeys.given``: what ``mfcl`` does).

    Raises:
        FloorplanError: unknown extension, missing file, an option for another format, or
            whatever the reader rejects.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FLOORPLAN_SUFFIXES:
        raise FloorplanError(
            f"{path}: unknown floor-plan format {suffix or '(no extension)'!r}; "
            f"expected one of {', '.join(FLOORPLAN_SUFFIXES)}"
        )
    if not path.is_file():
        raise FloorplanError(f"{path}: file not found")
    if storey is not None and suffix not in (".ifc", ".geojson", ".json"):
        raise FloorplanError(f"{path}: storey={storey!r} applies to IFC and GeoJSON files only")
    rosmap = suffix in (".yaml", ".yml")
    for flag, value in (("free_thresh", free_thresh), ("occupied_thresh", occupied_thresh)):
        if value is not None and not rosmap:
            raise FloorplanError(f"{path}: {flag}={value!r} applies to ROS maps (.yaml) only")
    if suffix in (".geojson", ".json"):
        from mfcl_jax.floorplan.building import geojson_building

        fp = geojson_building(path, storey, every)
    elif suffix == ".ifc":
        from mfcl_jax.floorplan.building import ifc_building

        fp = ifc_building(path, storey=storey, cut_height=cut_height, every=every)
    else:
        from mfcl_jax.floorplan.rosmap import load_rosmap

        fp = load_rosmap(path, free_thresh=free_thresh, occupied_thresh=occupied_thresh)
    if fp.walls_derived:
        warnings.warn(
            f"{path}: the plan has rooms and no walls; {len(fp.walls)} wall segments were drawn "
            "along the rooms' boundaries (edges two rooms share are left open) and, as it "
            "marks no doors, rooms facing each other across a wall are taken as joined "
            "anywhere on it",
            FloorplanWarning,
            stacklevel=2,
        )
    if not local:
        return fp
    from mfcl_jax.floorplan.origin import local_origin

    return local_origin(fp)


def load_building(paths, storey=None, **opts) -> Floorplan:
    """What ``mfcl`` reads: ``load_floorplan(..., every=True)`` of one file; several files
    (``--floorplan`` given more than once, e.g. one ROS map per storey) are one storey each,
    named by the file's stem and stacked. A ``storey`` named (an IFC storey, a GeoJSON level,
    a file's stem) is marked given, and every storey is still weighed."""
    paths = [paths] if isinstance(paths, str | Path) else list(paths)
    if len(paths) == 1:
        return load_floorplan(paths[0], storey=storey, every=True, **opts)
    stems = [Path(p).stem for p in paths]
    if storey is not None and str(storey) not in stems:
        raise FloorplanError(f"storey {storey!r}: not one of the plans {stems} (file stems)")
    from mfcl_jax.floorplan.building import stack_files

    loaded = [(Path(p), load_floorplan(p, **{**opts, "local": False})) for p in paths]
    return stack_files(loaded, None if storey is None else str(storey))


def floorplan_files(path) -> list[Path]:
    """The files a load of ``path`` reads: the plan itself and, for a ROS map, its image (so
    an output can be checked against them before the run; an unreadable YAML lists only
    itself, the loader reports it)."""
    path = Path(path)
    files = [path]
    if path.suffix.lower() in (".yaml", ".yml") and path.is_file():
        import yaml

        try:
            image = (yaml.safe_load(path.read_text()) or {}).get("image")
        except (yaml.YAMLError, AttributeError, OSError, UnicodeDecodeError):
            image = None
        if isinstance(image, str) and image:
            files.append(path.parent / image)
    return files
