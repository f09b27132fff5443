"""A family scene's floor plan as GeoJSON (its picture: ``report.plots_scene.plot_family``)."""

from __future__ import annotations

from pathlib import Path

from mfcl_jax.floorplan.geojson_write import save_geojson

__all__ = ["write_family_geojson"]


def write_family_geojson(scene, path) -> Path:
    """Writes the scene's floor plan (walls, rooms, doors; not clutter or walks) as GeoJSON."""
    return Path(save_geojson(scene.floorplan, path))
