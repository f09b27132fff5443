"""The benchmark's runs as ``Recording``s: procedural buildings, IFC tours, real log windows,
and the fault axes.

Each recording's ``meta`` holds ``family``, ``seed``, ``walk``, ``fault`` and ``level`` (empty
for the nominal runs), which the report groups by. Floor plans of the IFC models are cached
as GeoJSON under the cache folder, so a re-run does not re-cut the IFC files.
"""

from __future__ import annotations

import functools
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from mfcl_jax.bench.config import FAULTS, IFC_MODELS, NEAR_SYMMETRIC, PROCEDURAL, BenchmarkConfig
from mfcl_jax.sim import LidarParams, SimParams, TrajectoryParams
from mfcl_jax.sources.data import data_dir

__all__ = ["DATA", "check_logs", "nominal_recordings", "fault_recordings", "ifc_floorplan"]

DATA = data_dir()


def _log(cfg, msg):
    if cfg.progress:
        print(f"[benchmark] {msg}", file=sys.stderr, flush=True)


def _tag(recs, **meta):
    from mfcl_jax.sources import Recording

    return [Recording(r.name, r.floorplan, r.seq, r.truth, {**r.meta, **meta}) for r in recs]


@functools.lru_cache(maxsize=256)
def _scene(family: str, seed: int):
    """One ``Scene`` object per (family, seed): its nominal runs and every fault run that
    keeps the plan share one ``Floorplan``, so features, rasters and gate maps are built once
    (the fault constructors return new scenes, never change this one)."""
    from mfcl_jax.sim import families

    return families.make_scene(family, seed)


def _procedural(family: str, seed: int, walks: int, params: SimParams, scene=None, **meta):
    from mfcl_jax.sources.simulated import simulate

    scene = scene or _scene(family, seed)
    names = list(scene.trajectories)[:walks]
    recs = simulate(scene, names, [seed], params)
    meta = {"fault": "", "level": "", **meta}
    out = _tag(recs, family=family, source="procedural", seed=seed, **meta)
    for r, n in zip(out, names, strict=True):
        r.meta["walk"] = n
    return out


def ifc_floorplan(model: str, cache: str | None):
    """The IFC model's floor plan (cached as GeoJSON in ``cache``)."""
    import hashlib

    from mfcl_jax.floorplan import ifc, ifc_rooms, ifc_section
    from mfcl_jax.floorplan.geojson import load_geojson
    from mfcl_jax.floorplan.geojson_write import save_geojson
    from mfcl_jax.floorplan.load import load_floorplan

    file, storey = IFC_MODELS[model]
    if cache:
        # keyed by the loader's code: a plan cut by an older loader is not reused
        h = hashlib.sha1()
        for mod in (ifc, ifc_section, ifc_rooms):
            h.update(Path(mod.__file__).read_bytes())
        version = h.hexdigest()[:10]
        path = Path(cache).expanduser() / "floorplans" / f"{model}-{version}.geojson"
        if path.is_file():
            return load_geojson(path)
    fp = load_floorplan(DATA / file, storey=storey)
    if cache:
        save_geojson(fp, path)
    return fp


def _ifc(model: str, seed: int, n: int, cfg: BenchmarkConfig):
    from mfcl_jax.sim.scenes import Scene
    from mfcl_jax.sources.simulated import simulate
    from mfcl_jax.sources.walks import random_tours

    fp = ifc_floorplan(model, cfg.cache)
    tours = random_tours(fp, n, seed=1000 + seed)
    if not tours:
        return []
    trajs = {f"tour{i}": w for i, w in enumerate(tours)}
    scene = Scene(f"ifc:{model}", fp, np.zeros((0, 2, 2)), trajs)
    recs = simulate(scene, list(trajs), [seed], SimParams())
    out = _tag(recs, family=f"ifc:{model}", source="ifc", seed=seed, fault="", level="")
    for r, n_ in zip(out, trajs, strict=True):
        r.meta["walk"] = n_
    return out


def _tower(kind: str, seed: int, n_storeys: int = 4):
    """One walk per storey of tower ``seed``, against the stacked plan; the truth moved into
    the stacked plan's frame (``Storeys.place``)."""
    from mfcl_jax.floorplan.storeys import stack_storeys
    from mfcl_jax.se2 import compose_host
    from mfcl_jax.sim.families.tower import make_tower
    from mfcl_jax.sources.recording import GroundTruth, Recording
    from mfcl_jax.sources.simulated import simulate

    tw = make_tower(kind, seed, n_storeys)
    plan, st = stack_storeys(tw.storeys, name=tw.name)
    out = []
    for s, scene in enumerate(tw.scenes):
        names = sorted(scene.trajectories)
        w = names[s % len(names)]
        rec = simulate(scene, [w], [1000 * seed + s], SimParams())[0]
        poses = compose_host(np.broadcast_to(st.place[s], rec.truth.poses.shape), rec.truth.poses)
        truth = GroundTruth(rec.truth.times, poses, rec.truth.source)
        meta = dict(rec.meta, storey=st.names[s], congruent=bool(tw.congruent[s]))
        out.append(Recording(f"{tw.name}/{st.names[s]}/{w}", plan, rec.seq, truth, meta))
    out = _tag(out, family=f"tower:{kind}", source="procedural", seed=seed, fault="", level="")
    for r in out:
        r.meta["walk"] = r.name.rsplit("/", 1)[-1]
    return out


def _logs(family: str, cfg: BenchmarkConfig):
    from mfcl_jax.sources import logs

    cache = str(Path(cfg.cache).expanduser() / "maps") if cfg.cache else None
    if family == "bag:intel":
        recs = logs.bag_recordings(cfg.log_windows, cfg.log_length, cache_dir=cache)
    else:
        recs = logs.log_recordings(family[4:], cfg.log_windows, cfg.log_length, cache_dir=cache)
    out = _tag(recs, family=family, source="log", fault="", level="")
    for r in out:
        r.meta.setdefault("seed", 0)
        r.meta["walk"] = r.meta.get("trajectory", r.name)
    return out


def check_logs(cfg: BenchmarkConfig) -> None:
    """Every configured log holds ``log_windows`` disjoint windows of ``log_length`` metres
    (checked on the log's travel before any work starts; ``BenchmarkError`` otherwise)."""
    from mfcl_jax.bench.config import BenchmarkError
    from mfcl_jax.sources import logs
    from mfcl_jax.sources.logwindows import plan_windows
    from mfcl_jax.windows import travelled

    names = {f[4:] if f.startswith("log:") else "intel" for f in cfg.families
             if f.startswith(("log:", "bag:"))}  # fmt: skip
    for name in sorted(names):
        try:
            plan_windows(travelled(logs.read_log(name).poses), cfg.log_windows,
                         cfg.log_length, name)  # fmt: skip
        except ValueError as e:
            raise BenchmarkError(
                f"benchmark: log_windows={cfg.log_windows} with log_length={cfg.log_length:g} "
                f"does not fit: {e}"
            ) from None


def nominal_recordings(cfg: BenchmarkConfig) -> list:
    """Every nominal run of the configuration, family by family."""
    out = []
    for fam in cfg.families:
        n0 = len(out)
        if fam in PROCEDURAL:
            for seed in range(cfg.seeds):
                out += _procedural(fam, seed, cfg.walks, SimParams())
        elif fam.startswith("ifc:"):
            for seed in range(cfg.seeds):
                out += _ifc(fam[4:], seed, cfg.ifc_walks, cfg)
        elif fam.startswith("tower:"):
            for seed in range(cfg.seeds):
                out += _tower(fam[6:], seed)
        else:
            out += _logs(fam, cfg)
        _log(cfg, f"{fam}: {len(out) - n0} runs")
    return out


def _faulted(axis: str, level, fam: str, seed: int):
    """(scene or None, SimParams) of one fault level for one base building."""
    from mfcl_jax.sim import families

    scene = _scene(fam, seed)
    lidar, traj = LidarParams(), TrajectoryParams()
    sim = SimParams()
    if axis == "drift":
        sim = replace(sim, trajectory=replace(traj, drift_xy=float(level)))
    elif axis == "yaw_drift":
        sim = replace(sim, trajectory=replace(traj, drift_yaw_deg_per_m=float(level)))
    elif axis == "dropout":
        sim = replace(sim, lidar=replace(lidar, dropout=float(level)))
    elif axis == "range_noise":
        sim = replace(sim, lidar=replace(lidar, sigma=float(level)))
    elif axis == "restart":
        sim = replace(sim, restart_at=float(level))
    elif axis == "latency":
        sim = replace(sim, odom_latency=float(level))
    elif axis == "near_symmetric":
        scene = families.with_near_symmetry(scene, str(level), 0)
    elif axis == "clutter":
        scene = families.with_clutter(scene, float(level), seed) if level else scene
    elif axis == "as_built":
        scene = families.with_as_built(scene, str(level), seed)
    elif axis == "scale":
        scene = families.with_scale_error(scene, float(level)) if level != 1.0 else scene
    elif axis == "plan":
        scene = families.with_plan_format(scene, str(level))
    else:
        raise KeyError(axis)
    return scene, sim


# The nominal setting of a numeric fault axis (the first level): its runs are the nominal
# runs of the base set, reused rather than simulated again (``nominal_level_rows``).
NOMINAL_LEVEL = {a: FAULTS[a][0] for a in ("drift", "yaw_drift", "clutter", "dropout",
                                           "range_noise", "scale")}  # fmt: skip


def reuses_nominal(cfg: BenchmarkConfig, axis: str, level, fam: str, seed: int) -> bool:
    """Whether this fault run is a nominal run the configuration already has."""
    return (axis in NOMINAL_LEVEL and level == NOMINAL_LEVEL[axis] and fam in cfg.families
            and seed < cfg.seeds)  # fmt: skip


def near_symmetric_seeds(family: str, n: int) -> list[int]:
    """The first ``n`` seeds of ``family`` whose plan takes the near-symmetric stub."""
    from mfcl_jax.sim.families import NotApplicable, make_scene, with_near_symmetry

    out = []
    for seed in range(64):
        if len(out) == n:
            break
        try:
            with_near_symmetry(make_scene(family, seed), "stub_built", 0)
            out.append(seed)
        except NotApplicable:
            continue
    return out


def _fault_base(cfg: BenchmarkConfig, axis: str) -> tuple[list, int]:
    """(family, seed) pairs an axis re-runs, and the walks of each."""
    if axis == "near_symmetric":
        return [(f, s) for f, n in NEAR_SYMMETRIC.items() if f in cfg.families
                for s in near_symmetric_seeds(f, n)], 2  # fmt: skip
    fams = [f for f in cfg.families if f in PROCEDURAL]
    return [(f, s) for f in fams for s in range(cfg.fault_seeds)], 1


def fault_recordings(cfg: BenchmarkConfig) -> list:
    """The base set (first walk of every procedural family, ``fault_seeds`` seeds) at every
    level of every configured fault axis. Runs at an axis's nominal level that the nominal
    runs already hold are not simulated again; a deviation a building cannot take (a door
    that cannot move, no wall that can go) is skipped and said so."""
    from mfcl_jax.sim.families import NotApplicable

    out = []
    for axis in cfg.faults:
        n0 = len(out)
        skipped = []
        base, walks = _fault_base(cfg, axis)
        for level in FAULTS[axis]:
            for fam, seed in base:
                if reuses_nominal(cfg, axis, level, fam, seed):
                    continue
                try:
                    scene, sim = _faulted(axis, level, fam, seed)
                except NotApplicable as e:
                    skipped.append(f"{fam}/{seed} {level}: {e}")
                    continue
                out += _procedural(fam, seed, walks, sim, scene=scene, fault=axis,
                                   level=str(level))  # fmt: skip
        _log(cfg, f"fault {axis}: {len(out) - n0} runs")
        for s in skipped:
            _log(cfg, f"fault {axis}: not applicable, skipped: {s}")
    return out
