"""Floor plans: the model, its rasters, loaders and built-in stand-in buildings."""

from mfcl_jax.floorplan.geojson import (
    floorplan_from_geojson,
    floorplan_to_geojson,
    load_geojson,
    save_geojson,
)
from mfcl_jax.floorplan.ifc import load_ifc
from mfcl_jax.floorplan.load import load_floorplan
from mfcl_jax.floorplan.model import Door, Floorplan, FloorplanError, Room
from mfcl_jax.floorplan.raster import Rasters, bilinear, lookup, pad_to, rasterize
from mfcl_jax.floorplan.rosmap import load_rosmap

__all__ = [
    "Door",
    "Floorplan",
    "FloorplanError",
    "Room",
    "Rasters",
    "bilinear",
    "lookup",
    "pad_to",
    "rasterize",
    "floorplan_from_geojson",
    "floorplan_to_geojson",
    "load_geojson",
    "save_geojson",
    "load_floorplan",
    "load_ifc",
    "load_rosmap",
]
