"""Floor plans: the model, its rasters, loaders and built-in stand-in buildings.

Names are imported on first use (PEP 562): ``import mfcl_jax.floorplan.model`` (the error
type every command catches) must not pull in JAX, IFC or SciPy, so that ``mfcl --help`` and
argument errors stay instant.
"""

from importlib import import_module

_WHERE = {
    "floorplan_from_geojson": "geojson",
    "floorplan_to_geojson": "geojson_write",
    "load_geojson": "geojson",
    "save_geojson": "geojson_write",
    "load_ifc": "ifc",
    "load_floorplan": "load",
    "Door": "model",
    "Floorplan": "model",
    "FloorplanError": "model",
    "FloorplanWarning": "model",
    "Room": "model",
    "local_origin": "origin",
    "shift_plan": "origin",
    "to_local_frame": "origin",
    "to_plan_frame": "origin",
    "Rasters": "raster",
    "bilinear": "raster",
    "lookup": "raster",
    "pad_to": "raster",
    "rasterize": "raster",
    "load_rosmap": "rosmap",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f"{__name__}.{_WHERE[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_WHERE))
