"""Scenario configuration: frozen dataclasses that map one to one onto scenario YAML files.

Bundled scenarios live in ``scenes/scenarios/NAME.yaml``; :data:`SCENARIOS` lists them and is
the one list every command uses. Every field can be overridden with dotted keys
(``spacing.mean_m=12``), from Python or from ``aerial-synth place --set KEY=VALUE``.

Validation lives here, in one place: :func:`parse_scenario` checks every field (type, finite,
range) with :mod:`aerial_synth.validators` and names it in the error, prefixed by where it came
from: ``scenarios/jam.yaml: spacing.mean_m: expected ...`` for a file,
``--set spacing.mean_m: expected ...`` for an override. The dataclasses validate again in
``__post_init__`` (same helpers), so a config built from Python is checked too.
"""

from __future__ import annotations

import copy
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .. import validators as V
from ..errors import ConfigError, PlacementError
from ..safe_input import load_yaml, read_text
from .parking_config import PARKING_KINDS, ParkingConfig, parse_parking
from .spacing import SpacingSampler

__all__ = [
    "ProbeConfig",
    "LinesConfig",
    "ScenarioConfig",
    "SCENARIOS",
    "scenario_dir",
    "list_scenarios",
    "load_scenario",
    "parse_scenario",
    "parse_overrides",
]

#: how far a tile's placement window reaches past its core when --margin-m is left out
#: (place-tiled and a tiled export): the one home of that default
DEFAULT_MARGIN_M = 60.0

#: Upper bounds that keep a run finite and the geometry sane (metres unless named).
MAX_COUNT = 10_000_000
MAX_DISTANCE_M = 10_000.0


def scenario_dir() -> Path:
    return Path(__file__).resolve().parents[1] / "data" / "scenes" / "scenarios"


def list_scenarios() -> list[str]:
    """Names of the bundled scenario files, sorted."""
    d = scenario_dir()
    return sorted(p.stem for p in d.glob("*.yaml")) if d.is_dir() else []


#: The bundled scenarios (one per file in ``scenes/scenarios``): the single list that
#: ``place``, ``render`` and ``export`` accept besides a .yaml path.
SCENARIOS: tuple[str, ...] = tuple(list_scenarios())


def _opt(check, name, v, **kw):
    return None if v is None else check(name, v, **kw)


#: Most steps one probe direction may march (max_distance_m / step_m): the thesis's 0.05 m
#: over 16 m is 320; 1e-9 m asked for 1.6e10 and never finished.
MAX_PROBE_STEPS = 20_000


@dataclass(frozen=True)
class ProbeConfig:
    """Line-trace probing (thesis §3.2.2): 0.05 m steps, every 10 degrees.

    step_m        : march step along a probe direction, (0, 1] m
    directions    : number of directions around a seed point (36 = every 10 degrees), 4..360
    max_distance_m: how far a probe marches before giving up (no edge found), (0, 200] m
    side_angle_deg: the second direction of the two-direction re-probe (thesis: 10 degrees)
    refine_steps  : bisection iterations between the last road step and the first non-road
                    step (0 = the thesis's 0.05 m resolution; 6 gives < 1 mm), 0..12
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
        p = "probe."
        s = object.__setattr__
        s(self, "step_m", V.in_range(p + "step_m", self.step_m, 0.0, 1.0, lo_open=True))
        s(self, "directions", V.integer(p + "directions", self.directions, 4, 360))
        s(self, "max_distance_m", V.in_range(p + "max_distance_m", self.max_distance_m, 0.0, 200.0,
                                             lo_open=True))
        s(self, "side_angle_deg", V.in_range(p + "side_angle_deg", self.side_angle_deg, 0.0, 90.0,
                                             lo_open=True, hi_open=True))
        s(self, "refine_steps", V.integer(p + "refine_steps", self.refine_steps, 0, 12))
        s(self, "median_max_m", V.in_range(p + "median_max_m", self.median_max_m, 0.0, 100.0))
        s(self, "max_turn_deg", V.in_range(p + "max_turn_deg", self.max_turn_deg, 0.0, 180.0,
                                           lo_open=True))
        s(self, "edge_jump_m", V.in_range(p + "edge_jump_m", self.edge_jump_m, 0.0, 20.0, lo_open=True))
        steps = self.max_distance_m / self.step_m
        if steps > MAX_PROBE_STEPS:  # each probe marches this many steps in every direction
            raise ConfigError(
                f"{p}step_m: expected at least {p}max_distance_m / {MAX_PROBE_STEPS:,} = "
                f"{self.max_distance_m / MAX_PROBE_STEPS:g} m (a probe would march {steps:,.0f} "
                f"steps), got {V.show(self.step_m)}")


@dataclass(frozen=True)
class LinesConfig:
    """Vehicles per traffic line: N ~ Normal(mean, sd), at least ``min``.

    mean : > 0 (and at most 10 million), sd : >= 0, min : integer >= 1
    """

    mean: float = 30.0
    sd: float = 8.0
    min: int = 1

    def __post_init__(self) -> None:
        p = "vehicles_per_line."
        s = object.__setattr__
        s(self, "mean", V.in_range(p + "mean", self.mean, 0.0, MAX_COUNT, lo_open=True))
        s(self, "sd", V.in_range(p + "sd", self.sd, 0.0, MAX_COUNT))
        s(self, "min", V.integer(p + "min", self.min, 1, MAX_COUNT))

    def sample(self, rng: np.random.Generator) -> int:
        return max(int(self.min), int(round(rng.normal(self.mean, self.sd))))


@dataclass(frozen=True)
class ScenarioConfig:
    """One traffic scenario.

    kind              : "lines" (thesis traffic lines) or "random" (EXP2 baseline: anywhere on
                        road, uniformly random heading)
    spacing           : centre-to-centre spacing law (ignored by "random")
    lane_offset_m     : d, distance from the road edge to the vehicle centre (half a 3.5 m lane),
                        (0, 50] m
    lane_offsets_m    : optional list of d values for multi-lane roads (thesis §6 future work):
                        each seeded line picks one lane, e.g. [1.75, 5.25, 8.75] for three
                        3.5 m lanes per direction; null = every line uses lane_offset_m
    fill_lanes        : fill every lane of a multi-lane carriageway: a finished line starts the
                        line of the next lane inwards (lane_width_m further from the edge) at
                        its first vehicle, the way a double lane starts the opposite one, while
                        that lane still lies on the line's side of the road (its half of an
                        undivided road, the whole carriageway of a divided one or one-way road)
    lane_width_m      : the lane width fill_lanes steps by, [2, 6] m
    traffic           : "right" (edge on the vehicle's right) or "left"
    double_lane_probability : chance that a finished line gets an opposite lane, [0, 1]
    gap_m             : the clearance kept between two vehicle footprints, [0, 10] m: two
                        bare footprints closer than gap_m are refused, gap_m apart or more are
                        accepted (each footprint is grown by gap_m / 2 on every side for the
                        overlap test)
    min_center_distance_m : optional thesis rule (8 m centre to centre); null = off
    lines / vehicles  : default amount when the caller gives neither (positive or null)
    seed_batch        : random traces per batch when looking for line seeds
    max_seed_attempts : give up seeding after this many random traces...
    seed_attempts_per_ha : ...or this many per hectare of the scene's extent, if more, [0, 1e6]
    """

    name: str = "jam"
    kind: str = "lines"
    spacing: SpacingSampler | None = None
    vehicles_per_line: LinesConfig = field(default_factory=LinesConfig)
    lane_offset_m: float = 1.75
    lane_offsets_m: tuple[float, ...] | None = None
    fill_lanes: bool = False
    lane_width_m: float = 3.5
    traffic: str = "right"
    double_lane_probability: float = 0.8
    gap_m: float = 0.5
    min_center_distance_m: float | None = None
    lines: int | None = 40
    vehicles: int | None = None
    probe: ProbeConfig = field(default_factory=ProbeConfig)
    seed_batch: int = 4096
    max_seed_attempts: int = 50000
    seed_attempts_per_ha: float = 2000.0
    #: parking, street-parking and mixed scenarios (placement/parking_config.py)
    parking: ParkingConfig | None = None

    def __post_init__(self) -> None:
        s = object.__setattr__
        if not isinstance(self.name, str) or not self.name.strip():
            raise ConfigError(f"name: expected a non-empty string, got {V.show(self.name)}")
        V.one_of("kind", self.kind, ("lines", "random") + tuple(PARKING_KINDS))
        if self.spacing is not None and not isinstance(self.spacing, SpacingSampler):
            raise ConfigError(f"spacing: expected a spacing block, got {V.show(self.spacing)}")
        if self.kind in ("lines", "mixed", "driveways") and self.spacing is None:
            raise ConfigError(f"spacing: a '{self.kind}' scenario needs a spacing block, got null")
        if self.parking is not None and not isinstance(self.parking, ParkingConfig):
            raise ConfigError(f"parking: expected a mapping, got {V.show(self.parking)}")
        if self.kind in PARKING_KINDS and self.parking is None:
            s(self, "parking", ParkingConfig())
        if not isinstance(self.vehicles_per_line, LinesConfig):
            raise ConfigError(f"vehicles_per_line: expected a mapping, got {V.show(self.vehicles_per_line)}")
        if not isinstance(self.probe, ProbeConfig):
            raise ConfigError(f"probe: expected a mapping, got {V.show(self.probe)}")
        V.one_of("traffic", self.traffic, ("right", "left"))
        s(self, "lane_offset_m", V.in_range("lane_offset_m", self.lane_offset_m, 0.0, 50.0, lo_open=True))
        if self.lane_offsets_m is not None:
            offs = V.sequence_of_numbers("lane_offsets_m", self.lane_offsets_m, positive_only=True)
            if not offs or max(offs) > 50.0:
                raise ConfigError(
                    f"lane_offsets_m: expected a non-empty list of distances in (0, 50] m or null, "
                    f"got {V.show(self.lane_offsets_m)}")
            s(self, "lane_offsets_m", offs)
        if not isinstance(self.fill_lanes, bool):
            raise ConfigError(f"fill_lanes: expected true or false, got {V.show(self.fill_lanes)}")
        s(self, "lane_width_m", V.in_range("lane_width_m", self.lane_width_m, 2.0, 6.0))
        s(self, "double_lane_probability",
          V.probability("double_lane_probability", self.double_lane_probability))
        s(self, "gap_m", V.in_range("gap_m", self.gap_m, 0.0, 10.0))
        s(self, "min_center_distance_m",
          _opt(V.in_range, "min_center_distance_m", self.min_center_distance_m, lo=0.0, hi=100.0))
        for k in ("lines", "vehicles"):
            s(self, k, _opt(V.integer, k, getattr(self, k), lo=1, hi=MAX_COUNT))
        s(self, "seed_batch", V.integer("seed_batch", self.seed_batch, 1, 1_000_000))
        s(self, "max_seed_attempts", V.integer("max_seed_attempts", self.max_seed_attempts, 1, 10**9))
        s(self, "seed_attempts_per_ha", V.in_range("seed_attempts_per_ha", self.seed_attempts_per_ha, 0.0, 1e6))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["spacing"] = self.spacing.to_dict() if self.spacing is not None else None
        d["parking"] = self.parking.to_dict() if self.parking is not None else None
        if d["lane_offsets_m"] is not None:
            d["lane_offsets_m"] = list(d["lane_offsets_m"])
        return d

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "<mapping>") -> "ScenarioConfig":
        """Build from a mapping (a scenario YAML's content); errors start with ``source: ``."""
        return parse_scenario(data, _Labels(source))


# ------------------------------------------------------------------------------- parsing


_SPACING_KEYS = tuple(f.name for f in fields(SpacingSampler))
_SPACING_OUTPUT_ONLY = ("distribution", "solved_loc_m", "solved_scale_m")  # from to_dict()
_LINES_KEYS = tuple(f.name for f in fields(LinesConfig))
_PROBE_KEYS = tuple(f.name for f in fields(ProbeConfig))
_SCENARIO_KEYS = tuple(f.name for f in fields(ScenarioConfig))


class _Labels:
    """Names a field for an error: ``--set spacing.mean_m`` when an override set it (or a key
    below it), else ``<source>: spacing.mean_m``."""

    def __init__(self, source: str, overridden: set[str] | None = None, override_label: str = "--set"):
        self.source = source
        self.overridden = overridden or set()
        self.override_label = override_label

    def __call__(self, path: str) -> str:
        if path in self.overridden:
            return f"{self.override_label} {path}"
        return f"{self.source}: {path}"

    def wrap(self, path: str, exc: ConfigError) -> ConfigError:
        """Re-label an error raised by a dataclass (whose message starts with the bare field)."""
        msg = str(exc)
        head, sep, rest = msg.partition(":")
        if sep and head.startswith(path):
            return ConfigError(self(head) + ":" + rest)
        return ConfigError(f"{self(path)}: {msg}")


def _block(labels: _Labels, path: str, value: Any, keys: tuple[str, ...],
           tolerated: tuple[str, ...] = ()) -> dict:
    if not isinstance(value, Mapping):
        if not path:
            raise ConfigError(f"{labels.source}: expected a mapping of scenario fields, "
                              f"got {V.show(value)}")
        V.mapping(labels(path), value)
    bad = [k for k in value if not isinstance(k, str)]
    if bad:
        where = labels(path) if path else labels.source
        raise ConfigError(f"{where}: keys must be names, got {V.show(bad[0])}")
    unknown = sorted(k for k in value if k not in keys and k not in tolerated)
    if unknown:
        key = unknown[0] if unknown[0].isidentifier() else V.show(unknown[0])  # one line, always
        raise ConfigError(f"{labels(path + '.' + key) if path else labels(key)}: "
                          f"unknown key; expected one of {', '.join(keys)}")
    return {k: v for k, v in value.items() if k in keys}


def _checked(labels: _Labels, prefix: str, data: dict, checks: dict) -> dict:
    """Apply one validator per key; the error names the key through ``labels``."""
    out = {}
    for k, v in data.items():
        check = checks[k]
        out[k] = check(labels(prefix + k), v)
    return out


def _num(lo=None, hi=None, lo_open=False, hi_open=False, nullable=False):
    def check(name, v):
        if v is None and nullable:
            return None
        return V.in_range(name, v, lo, hi, lo_open=lo_open, hi_open=hi_open)
    return check


_SPACING_CHECKS = {
    "skewness": _num(-1000.0, 1000.0),
    "mean_m": _num(0.0, lo_open=True),  # below max_m, checked by the sampler
    "sd_m": _num(0.0, lo_open=True),
    "min_m": _num(0.0, MAX_DISTANCE_M),
    "max_m": _num(0.0, MAX_DISTANCE_M, lo_open=True),
    "floor_m": _num(0.0, MAX_DISTANCE_M, nullable=True),
}


def parse_scenario(data: Any, labels: _Labels) -> ScenarioConfig:
    """Validate a scenario mapping field by field and build the :class:`ScenarioConfig`.

    Raises :class:`ConfigError` with one line naming the field (see :class:`_Labels`).
    """
    top = _block(labels, "", data, _SCENARIO_KEYS)
    kw: dict[str, Any] = {}
    for k, v in top.items():
        name = labels(k)
        if k == "spacing":
            if v is None:
                kw[k] = None
                continue
            sp = _block(labels, "spacing", v, _SPACING_KEYS, _SPACING_OUTPUT_ONLY)
            missing = [f for f in _SPACING_KEYS if f not in sp and f != "floor_m"]
            if missing:
                raise ConfigError(f"{labels('spacing.' + missing[0])}: missing; the spacing block "
                                  f"needs {', '.join(f for f in _SPACING_KEYS if f != 'floor_m')}")
            sp = _checked(labels, "spacing.", sp, _SPACING_CHECKS)
            try:
                kw[k] = SpacingSampler(**sp)
            except ConfigError as exc:
                raise labels.wrap("spacing", exc) from None
        elif k == "vehicles_per_line":
            vl = _block(labels, k, {} if v is None else v, _LINES_KEYS)
            try:
                kw[k] = LinesConfig(**vl)
            except ConfigError as exc:
                raise labels.wrap(k, exc) from None
        elif k == "probe":
            pr = _block(labels, k, {} if v is None else v, _PROBE_KEYS)
            try:
                kw[k] = ProbeConfig(**pr)
            except ConfigError as exc:
                raise labels.wrap(k, exc) from None
        elif k == "parking":
            kw[k] = None if v is None else parse_parking(v, labels)
        elif k == "name":
            if not isinstance(v, (str, int, float)) or isinstance(v, bool) or str(v).strip() == "":
                raise ConfigError(f"{name}: expected a non-empty string, got {V.show(v)}")
            kw[k] = str(v)
        elif k == "lane_offsets_m" and v is not None:
            offs = V.sequence_of_numbers(name, v, positive_only=True)
            if not offs or max(offs) > 50.0:
                raise ConfigError(f"{name}: expected a non-empty list of distances in (0, 50] m or "
                                  f"null, got {V.show(v)}")
            kw[k] = offs
        else:
            kw[k] = v
    try:
        return ScenarioConfig(**kw)
    except ConfigError as exc:
        msg = str(exc)
        head = msg.split(":", 1)[0]
        if head in _SCENARIO_KEYS:
            raise ConfigError(labels(head) + msg[len(head):]) from None
        raise ConfigError(f"{labels.source}: {msg}") from None


def parse_overrides(items: list[str] | None, option: str = "--set") -> dict:
    """Turn ["spacing.mean_m=12", "traffic=left"] into a nested dict (values parsed as YAML).

    Keys are dotted names (letters, digits, underscores); a later item wins over an earlier
    one. A malformed item raises :class:`ConfigError` naming it.
    """

    out: dict = {}
    for item in items or []:
        if not isinstance(item, str) or "=" not in item:
            raise ConfigError(f"{option} {V.show(item)}: expected KEY=VALUE, e.g. spacing.mean_m=12")
        key, _, raw = item.partition("=")
        parts = key.strip().split(".")
        if not all(p.isidentifier() and p.isascii() for p in parts):
            raise ConfigError(f"{option} {V.show(item)}: expected KEY=VALUE with a dotted key such as "
                              f"spacing.mean_m, got key {V.show(key)}")
        if "\n" in raw or "\r" in raw:
            val: Any = raw
        else:
            try:  # a YAML scalar or flow value, within the budgets; else the text itself
                val = load_yaml(raw, f"{option} {key}", ConfigError)
            except ConfigError:
                val = raw
        node = out
        for p in parts[:-1]:
            if not isinstance(node.get(p), dict):
                node[p] = {}
            node = node[p]
        node[parts[-1]] = val
    return out


def _leaf_paths(d: Mapping, prefix: str = "") -> set[str]:
    """Every dotted path of ``d`` (leaves and the blocks above them)."""
    out = set()
    for k, v in d.items():
        p = f"{prefix}{k}"
        out.add(p)
        if isinstance(v, Mapping):
            out |= _leaf_paths(v, p + ".")
    return out


def _deep_merge(base: dict, over: Mapping) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = _deep_merge(dict(out[k]), v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _bundled_label(p: Path) -> str:
    return f"scenarios/{p.name}" if p.parent == scenario_dir() else str(p)


def load_scenario(name_or_path: str | ScenarioConfig, overrides: Mapping | None = None,
                  override_label: str = "--set") -> ScenarioConfig:
    """Load a bundled scenario by name or a scenario YAML file, then apply overrides.

    Errors name the file and field (``scenarios/jam.yaml: spacing.mean_m: ...``), or the
    override (``--set spacing.mean_m: ...``; ``override_label`` replaces ``--set``).
    """

    if overrides is not None and not isinstance(overrides, Mapping):
        raise ConfigError(f"overrides: expected a mapping of key: value, got {V.show(overrides)}")
    if isinstance(name_or_path, ScenarioConfig):
        if not overrides:
            return name_or_path
        base = name_or_path.to_dict()
        source = f"scenario {name_or_path.name!r}"
    else:
        if not isinstance(name_or_path, (str, Path)) or str(name_or_path).strip() == "":
            raise PlacementError(f"--scenario: expected one of {', '.join(SCENARIOS)} or a .yaml file, "
                                 f"got {V.show(name_or_path)}")
        p = Path(str(name_or_path))
        if p.suffix.lower() in (".yaml", ".yml"):
            if not p.is_file():
                raise PlacementError(f"scenario file {p}: not found")
            source = str(p)
        else:
            p = scenario_dir() / f"{name_or_path}.yaml"
            if str(name_or_path) not in SCENARIOS or not p.is_file():
                raise PlacementError(
                    f"unknown scenario {str(name_or_path)!r}: expected one of {', '.join(SCENARIOS)} "
                    f"or a .yaml file"
                )
            source = _bundled_label(p)
        text = read_text(p, source, ConfigError)  # a regular file, size-capped, UTF-8
        key = (str(p), source, text, override_label)
        if not overrides and key in _PARSED:
            return _PARSED[key]
        base = load_yaml(text, source, ConfigError)  # nesting and alias budgets
        if base is None:
            base = {}
        if not isinstance(base, dict):
            raise ConfigError(f"{source}: expected a mapping at the top level, got {type(base).__name__}")
        base.setdefault("name", p.stem)
    over = dict(overrides or {})
    merged = _deep_merge(base, over)
    labels = _Labels(source, _leaf_paths(over), override_label)
    cfg = parse_scenario(merged, labels)
    if not overrides and not isinstance(name_or_path, ScenarioConfig):
        if len(_PARSED) >= 64:
            _PARSED.clear()
        _PARSED[key] = cfg
    return cfg


#: Scenario files parsed before, by (path, label, text, override label), without overrides:
#: a ScenarioConfig is immutable, and solving a spacing law takes milliseconds (a dataset
#: export loads its scenario once per placement group). Keyed by the text, so an edited
#: file is parsed again.
_PARSED: dict[tuple, ScenarioConfig] = {}
