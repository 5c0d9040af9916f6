"""Scenario configuration: frozen dataclasses that map one to one onto scenario YAML files.

Bundled scenarios live in ``scenes/scenarios/NAME.yaml`` (jam, normal, sparse, random).
Every field can be overridden with dotted keys (``spacing.mean_m=12``), from Python or from
``aerial-synth place --set KEY=VALUE``.
"""

from __future__ import annotations

import copy
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError, PlacementError
from .spacing import SpacingSampler

__all__ = [
    "ProbeConfig",
    "LinesConfig",
    "ScenarioConfig",
    "SCENARIOS",
    "scenario_dir",
    "list_scenarios",
    "load_scenario",
    "parse_overrides",
]

SCENARIOS = ("jam", "normal", "sparse", "random")


def scenario_dir() -> Path:
    return Path(__file__).resolve().parents[1] / "data" / "scenes" / "scenarios"


def list_scenarios() -> list[str]:
    d = scenario_dir()
    return sorted(p.stem for p in d.glob("*.yaml")) if d.is_dir() else []


@dataclass(frozen=True)
class ProbeConfig:
    """Line-trace probing (thesis §3.2.2): 0.05 m steps, every 10 degrees.

    step_m        : march step along a probe direction
    directions    : number of directions around a seed point (36 = every 10 degrees)
    max_distance_m: how far a probe marches before giving up (no edge found)
    side_angle_deg: the second direction of the two-direction re-probe (thesis: 10 degrees)
    refine_steps  : bisection iterations between the last road step and the first non-road
                    step (0 = the thesis's 0.05 m resolution; 6 gives < 1 mm)
    median_max_m  : a gap of non-road narrower than this beyond an edge, followed by road,
                    marks a divided road (central median): right-hand traffic keeps the
                    median on the left, and the opposite lane is across it
    max_turn_deg  : a new road direction more than this off the previous heading ends the
                    line (junction or road end)
    edge_jump_m   : the right edge moving more than this away from where the previous vehicle
                    had it ends the line (the road opens into a junction)
    """

    step_m: float = 0.05
    directions: int = 36
    max_distance_m: float = 16.0
    side_angle_deg: float = 10.0
    refine_steps: int = 6
    median_max_m: float = 14.0
    max_turn_deg: float = 30.0
    edge_jump_m: float = 1.5

    def __post_init__(self) -> None:
        _positive("probe.step_m", self.step_m)
        _positive("probe.edge_jump_m", self.edge_jump_m)
        _positive("probe.max_distance_m", self.max_distance_m)
        if int(self.directions) < 4:
            raise ConfigError(f"probe.directions: expected an integer >= 4, got {self.directions}")
        if not (0 < self.side_angle_deg < 90):
            raise ConfigError(f"probe.side_angle_deg: expected in (0, 90), got {self.side_angle_deg}")
        if self.refine_steps < 0:
            raise ConfigError(f"probe.refine_steps: expected >= 0, got {self.refine_steps}")
        if self.median_max_m < 0:
            raise ConfigError(f"probe.median_max_m: expected >= 0, got {self.median_max_m}")
        if not (0 < self.max_turn_deg <= 180):
            raise ConfigError(f"probe.max_turn_deg: expected in (0, 180], got {self.max_turn_deg}")


@dataclass(frozen=True)
class LinesConfig:
    """Vehicles per traffic line: N ~ Normal(mean, sd), at least ``min``."""

    mean: float = 30.0
    sd: float = 8.0
    min: int = 1

    def __post_init__(self) -> None:
        if self.sd < 0:
            raise ConfigError(f"vehicles_per_line.sd: expected >= 0, got {self.sd}")
        if self.min < 1:
            raise ConfigError(f"vehicles_per_line.min: expected >= 1, got {self.min}")

    def sample(self, rng: np.random.Generator) -> int:
        return max(int(self.min), int(round(rng.normal(self.mean, self.sd))))


def _positive(name: str, v: float) -> None:
    if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
        raise ConfigError(f"{name}: expected a positive number, got {v!r}")


@dataclass(frozen=True)
class ScenarioConfig:
    """One traffic scenario.

    kind              : "lines" (thesis traffic lines) or "random" (EXP2 baseline: anywhere on
                        road, uniformly random heading)
    spacing           : centre-to-centre spacing law (ignored by "random")
    lane_offset_m     : d, distance from the road edge to the vehicle centre (half a 3.5 m lane)
    lane_offsets_m    : optional list of d values for multi-lane roads (thesis §6 future work):
                        each seeded line picks one lane, e.g. [1.75, 5.25, 8.75] for three
                        3.5 m lanes per direction; null = every line uses lane_offset_m
    traffic           : "right" (edge on the vehicle's right) or "left"
    double_lane_probability : chance that a finished line gets an opposite lane
    gap_m             : clearance kept between footprints (each footprint grows by gap/2)
    min_center_distance_m : optional thesis rule (8 m centre to centre); null = off
    lines / vehicles  : default amount when the caller gives neither
    """

    name: str = "jam"
    kind: str = "lines"
    spacing: SpacingSampler | None = None
    vehicles_per_line: LinesConfig = field(default_factory=LinesConfig)
    lane_offset_m: float = 1.75
    lane_offsets_m: tuple[float, ...] | None = None
    traffic: str = "right"
    double_lane_probability: float = 0.8
    gap_m: float = 0.5
    min_center_distance_m: float | None = None
    lines: int | None = 40
    vehicles: int | None = None
    probe: ProbeConfig = field(default_factory=ProbeConfig)
    seed_batch: int = 4096
    max_seed_attempts: int = 50000

    def __post_init__(self) -> None:
        if self.kind not in ("lines", "random"):
            raise ConfigError(f"scenario {self.name!r} kind: expected 'lines' or 'random', got {self.kind!r}")
        if self.kind == "lines" and self.spacing is None:
            raise ConfigError(f"scenario {self.name!r}: a 'lines' scenario needs a spacing block")
        if self.traffic not in ("right", "left"):
            raise ConfigError(f"scenario {self.name!r} traffic: expected 'right' or 'left', got {self.traffic!r}")
        _positive(f"scenario {self.name!r} lane_offset_m", self.lane_offset_m)
        if self.lane_offsets_m is not None:
            offs = tuple(float(v) for v in self.lane_offsets_m) if isinstance(
                self.lane_offsets_m, (list, tuple)) else None
            if not offs or any(not (v > 0) for v in offs):
                raise ConfigError(
                    f"scenario {self.name!r} lane_offsets_m: expected a non-empty list of positive "
                    f"distances or null, got {self.lane_offsets_m!r}")
            object.__setattr__(self, "lane_offsets_m", offs)
        if self.gap_m < 0:
            raise ConfigError(f"scenario {self.name!r} gap_m: expected >= 0, got {self.gap_m}")
        if not (0 <= self.double_lane_probability <= 1):
            raise ConfigError(
                f"scenario {self.name!r} double_lane_probability: expected in [0, 1], got "
                f"{self.double_lane_probability}"
            )
        if self.min_center_distance_m is not None and self.min_center_distance_m < 0:
            raise ConfigError(f"scenario {self.name!r} min_center_distance_m: expected >= 0 or null")
        for k in ("lines", "vehicles"):
            v = getattr(self, k)
            if v is not None and (not isinstance(v, int) or v < 1):
                raise ConfigError(f"scenario {self.name!r} {k}: expected a positive integer or null, got {v!r}")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["spacing"] = self.spacing.to_dict() if self.spacing is not None else None
        return d

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "<mapping>") -> "ScenarioConfig":
        data = dict(data)
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"{source}: unknown scenario field(s) {unknown}; expected {sorted(known)}")
        try:
            sp = data.get("spacing")
            if sp is not None:
                sp = dict(sp)
                sp.pop("distribution", None)
                sp.pop("solved_loc_m", None)
                sp.pop("solved_scale_m", None)
                data["spacing"] = SpacingSampler(**sp)
            if "vehicles_per_line" in data and data["vehicles_per_line"] is not None:
                data["vehicles_per_line"] = LinesConfig(**data["vehicles_per_line"])
            if "probe" in data and data["probe"] is not None:
                data["probe"] = ProbeConfig(**data["probe"])
            return cls(**data)
        except TypeError as exc:
            raise ConfigError(f"{source}: {exc}") from None


def parse_overrides(items: list[str] | None) -> dict:
    """Turn ["spacing.mean_m=12", "traffic=left"] into a nested dict (values parsed as YAML)."""
    import yaml

    out: dict = {}
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE, e.g. spacing.mean_m=12")
        key, _, raw = item.partition("=")
        try:
            val = yaml.safe_load(raw)
        except yaml.YAMLError:
            val = raw
        node = out
        parts = key.strip().split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = val
    return out


def _deep_merge(base: dict, over: Mapping) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = _deep_merge(dict(out[k]), v)
        else:
            out[k] = v
    return out


def load_scenario(name_or_path: str | ScenarioConfig, overrides: Mapping | None = None) -> ScenarioConfig:
    """Load a bundled scenario by name or a scenario YAML file, then apply overrides."""
    import yaml

    if isinstance(name_or_path, ScenarioConfig):
        if not overrides:
            return name_or_path
        base = name_or_path.to_dict()
        source = f"scenario {name_or_path.name!r}"
    else:
        p = Path(str(name_or_path))
        if p.suffix.lower() in (".yaml", ".yml"):
            if not p.is_file():
                raise PlacementError(f"scenario file {p}: not found")
            source = str(p)
        else:
            p = scenario_dir() / f"{name_or_path}.yaml"
            if not p.is_file():
                raise PlacementError(
                    f"unknown scenario {name_or_path!r}: expected one of {', '.join(list_scenarios())} "
                    f"or a .yaml file"
                )
            source = str(p)
        try:
            base = yaml.safe_load(p.read_text()) or {}
        except yaml.YAMLError as exc:
            raise ConfigError(f"{p}: broken YAML ({str(exc).splitlines()[0]})") from None
        if not isinstance(base, dict):
            raise ConfigError(f"{p}: expected a mapping at the top level, got {type(base).__name__}")
        base.setdefault("name", p.stem)
    merged = _deep_merge(base, overrides or {})
    return ScenarioConfig.from_mapping(merged, source=source)
