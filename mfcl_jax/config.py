"""Hydra configuration: dataclass schemas for every config group, checked on load.

The YAML files under ``conf/`` fill these schemas; ``to_study`` unpacks a composed config into
plain parameter objects (``SimParams``, ``FrontendParams``, ``DecisionParams``) before any
kernel sees it. A misspelt key or a wrong type fails at composition, naming the key.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, ListConfig, OmegaConf

from mfcl_jax.decision.params import DecisionParams
from mfcl_jax.frontend.params import FrontendParams
from mfcl_jax.sim import SimParams
from mfcl_jax.windows import WindowParams

__all__ = ["StudyConfig", "register_configs", "to_study", "as_list", "build"]

# YAML writes angles in degrees: ``delta_theta: ${deg:18}``.
if not OmegaConf.has_resolver("deg"):
    OmegaConf.register_new_resolver("deg", lambda v: math.radians(float(v)))


@dataclass
class StudyConfig:
    """The sweep: which buildings, scales and seeds, and every parameter group.

    Attributes:
        scenes: built-in stand-in buildings to run.
        d_s: trajectory scales (m); a scalar or a list (all batched in one process).
        seeds: number of seeds (``seed0 .. seed0 + seeds - 1``).
        seed0: first seed.
        main_seed: the seed whose single run fills the paper-style tables.
        out: output folder for tables and figures.
        figures: draw figures.
        density_factor: candidate-pool growth for the density-immunity test (paper: ~13x).
        density_run: ``trajectory@d_s`` of the density-immunity run (paper: T2 at 6 m).
        progress: print progress lines.
    """

    scenes: list[str] = field(default_factory=lambda: ["three_rooms", "symmetric_bays"])
    d_s: list[float] = field(default_factory=lambda: [5.0, 6.0, 7.0])
    seeds: int = 10
    seed0: int = 0
    main_seed: int = 0
    out: str = "results"
    figures: bool = True
    density_factor: int = 13
    density_run: str = "T2@6"
    progress: bool = True
    sim: SimParams = field(default_factory=SimParams)
    window: WindowParams = field(default_factory=WindowParams)
    frontend: FrontendParams = field(default_factory=FrontendParams)
    decision: DecisionParams = field(default_factory=DecisionParams)


# The top-level schema is StudyConfig itself with the loosely typed fields relaxed: ``scenes``
# and ``d_s`` take a scalar (one multirun job) or a list, and the parameter groups are filled
# from their own group schemas (``register_configs``).
_LOOSE = ("scenes", "d_s", "sim", "window", "frontend", "decision")
_SweepSchema = dataclasses.make_dataclass(
    "_SweepSchema",
    [
        (f.name, Any, field(default=MISSING))
        if f.name in _LOOSE
        else (f.name, typing.get_type_hints(StudyConfig)[f.name], field(default=f.default))
        for f in dataclasses.fields(StudyConfig)
    ],
)


_MIRRORS: dict[type, type] = {}


def _mirror(cls: type) -> type:
    """A mutable twin of a frozen parameter dataclass (OmegaConf makes frozen nodes read-only).

    Field names, types and defaults are the parameter class's own, so the schema cannot drift
    from the code; nested parameter dataclasses are mirrored too.
    """
    if cls in _MIRRORS:
        return _MIRRORS[cls]
    hints = typing.get_type_hints(cls)
    specs = []
    for f in dataclasses.fields(cls):
        if f.name.startswith("_"):
            continue
        typ = hints[f.name]
        if dataclasses.is_dataclass(typ):
            typ = _mirror(typ)
            specs.append((f.name, typ, field(default_factory=typ)))
        elif f.default is not dataclasses.MISSING:
            specs.append((f.name, typ, field(default=f.default)))
        else:
            specs.append((f.name, typ, field(default_factory=f.default_factory)))
    _MIRRORS[cls] = dataclasses.make_dataclass(f"{cls.__name__}Schema", specs)
    return _MIRRORS[cls]


def build(cls: type, node):
    """Constructs the frozen parameter class ``cls`` from a config node (recursively)."""
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name.startswith("_") or f.name not in node:
            continue
        v = node[f.name]
        typ = hints[f.name]
        if dataclasses.is_dataclass(typ):
            v = build(typ, v)
        elif isinstance(v, DictConfig | ListConfig):
            v = OmegaConf.to_container(v, resolve=True)
            v = tuple(v) if isinstance(v, list) else v
        kwargs[f.name] = v
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as e:
        raise ValueError(f"config: invalid {cls.__name__}: {e}") from None


def register_configs() -> None:
    """Stores the schemas in Hydra's ConfigStore (idempotent)."""
    cs = ConfigStore.instance()
    cs.store(name="sweep_schema", node=_SweepSchema)
    cs.store(group="sim", name="schema", node=_mirror(SimParams))
    cs.store(group="window", name="schema", node=_mirror(WindowParams))
    cs.store(group="frontend", name="schema", node=_mirror(FrontendParams))
    cs.store(group="decision", name="schema", node=_mirror(DecisionParams))


def as_list(v) -> list:
    """A scalar or a list (Hydra ``ListConfig`` included) as a Python list."""
    if isinstance(v, ListConfig | list | tuple):
        return list(v)
    return [v]


def to_study(cfg: DictConfig) -> StudyConfig:
    """Unpacks a composed Hydra config into a ``StudyConfig`` of plain parameter objects."""
    d_s = [float(v) for v in as_list(cfg.d_s)]
    scenes = [str(s) for s in as_list(cfg.scenes)]
    if not d_s or any(not (v > 0 and math.isfinite(v)) for v in d_s):
        raise ValueError(f"config: d_s must be positive numbers, got {d_s}")
    if int(cfg.seeds) < 1:
        raise ValueError(f"config: seeds must be >= 1, got {cfg.seeds}")
    plain = {f.name: cfg[f.name] for f in dataclasses.fields(StudyConfig) if f.name not in _LOOSE}
    return StudyConfig(
        scenes=scenes,
        d_s=d_s,
        sim=build(SimParams, cfg.sim),
        window=build(WindowParams, cfg.window),
        frontend=build(FrontendParams, cfg.frontend),
        decision=build(DecisionParams, cfg.decision),
        **plain,
    )
