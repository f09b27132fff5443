"""Shared by the input tests (odometry rates, units, bags): a two-room plan, a constant-velocity
truth whose heading crosses pi, 10 Hz scans and the dataset folder written from them."""

from __future__ import annotations

import warnings

import numpy as np
from shapely.geometry import box

from mfcl_jax.floorplan import Door, Floorplan, Room
from mfcl_jax.sources import write_dataset

T0 = 1000.0


def _plan(k: float = 1.0) -> Floorplan:
    walls = k * np.array(
        [[[0, 0], [8, 0]], [[8, 0], [8, 4]], [[8, 4], [0, 4]], [[0, 4], [0, 0]],
         [[4, 0], [4, 1.5]], [[4, 2.5], [4, 4]]], float,
    )  # fmt: skip
    return Floorplan(
        walls=walls,
        thickness=0.15 * k,
        rooms=(Room("a", box(0, 0, 4 * k, 4 * k)), Room("b", box(4 * k, 0, 8 * k, 4 * k))),
        doors=(Door(k * np.array([[4, 1.5], [4, 2.5]]), ("a", "b")),),
        name=f"plan x{k:g}",
    )


def _truth(t) -> np.ndarray:
    """A constant-velocity path (so linear interpolation is exact) whose heading crosses pi."""
    dt = np.asarray(t, np.float64) - T0
    yaw = np.arctan2(np.sin(2.9 + 0.5 * dt), np.cos(2.9 + 0.5 * dt))
    return np.stack([1.0 + 0.3 * dt, 2.0 + 0.1 * dt, yaw], -1)


def _scans(n, seed=0, k=1.0):
    rng = np.random.default_rng(seed)
    return [k * rng.normal(size=(30, 2)) for _ in range(n)]


def _scan_times(n=20):
    # 10 Hz, between the 100 Hz odometry stamps (3.7 ms after each tick).
    return T0 + 0.1 * np.arange(n) + 0.0037


def _dataset(tmp_path, name="ref", times=None, **kw):
    times = _scan_times() if times is None else times
    plan = kw.pop("plan", _plan())
    scans = kw.pop("scans", _scans(len(times)))
    return write_dataset(tmp_path / name, plan, times, scans, _truth(times), **kw)


def _yaw_err(a, b) -> float:
    return float(np.max(np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))))


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return fn(*a, **kw)
