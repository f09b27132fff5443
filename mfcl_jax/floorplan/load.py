"""One entry point for every floor-plan file format."""

from __future__ import annotations

from pathlib import Path

from mfcl_jax.floorplan.model import Floorplan, FloorplanError

__all__ = ["load_floorplan", "FLOORPLAN_SUFFIXES"]

FLOORPLAN_SUFFIXES = (".geojson", ".json", ".ifc", ".yaml", ".yml")


def load_floorplan(path, storey=None, cut_height: float = 1.0) -> Floorplan:
    """Loads a floor plan, choosing the reader by the file extension.

    Args:
        path: ``.geojson``/``.json`` (GeoJSON), ``.ifc`` (IFC model), ``.yaml``/``.yml``
            (ROS map_server map).
        storey: IFC storey name or elevation (IFC only).
        cut_height: IFC cutting-plane height above the storey (m).

    Raises:
        FloorplanError: unknown extension, missing file, or whatever the reader rejects.
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
    if storey is not None and suffix != ".ifc":
        raise FloorplanError(f"{path}: storey={storey!r} applies to IFC files only")
    if suffix in (".geojson", ".json"):
        from mfcl_jax.floorplan.geojson import load_geojson

        return load_geojson(path)
    if suffix == ".ifc":
        from mfcl_jax.floorplan.ifc import load_ifc

        return load_ifc(path, storey=storey, cut_height=cut_height)
    from mfcl_jax.floorplan.rosmap import load_rosmap

    return load_rosmap(path)
