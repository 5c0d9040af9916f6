"""The ``parking`` block of a scenario: occupancy, parking manoeuvre, jitter, class mix,
lot detection and kerb parking settings (see docs/parking.md).

Scenario kinds that use it: ``parking`` (lots only), ``street-parking`` (kerbs only) and
``mixed`` (traffic lines plus lots and kerbs). Validated field by field with
:mod:`aerial_synth.validators`; errors name ``parking.<field>``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any, Mapping

from .. import validators as V
from ..errors import ConfigError, SceneError
from ..vehicles.model import CLASSES

__all__ = ["ParkingConfig", "parse_parking", "PARKING_KINDS", "PARKING_KEYS", "DEFAULT_DEPOT_MIX"]

#: scenario kinds -> (fills lots, fills kerbs, runs traffic lines)
PARKING_KINDS: dict[str, tuple[bool, bool, bool]] = {
    "parking": (True, False, False),
    "street-parking": (False, True, False),
    "mixed": (True, True, True),
    # driveways, side pads and farm yards (placement/driveways.py), kerbs and traffic
    "driveways": (False, True, True),
}
DEFAULT_MIX = {"small-vehicle": 0.96, "delivery_van": 0.04}
DEFAULT_DEPOT_MIX = {"city_bus": 0.45, "school_bus": 0.1, "coach": 0.2, "semi_trailer": 0.25}
_CLASSES = CLASSES


def _mix(name: str, value: Any) -> dict:
    V.mapping(name, value)
    if not value:
        raise ConfigError(f"{name}: expected at least one class or model with a weight, got {{}}")
    out = {}
    for k, w in value.items():
        if not isinstance(k, str) or not k.strip():
            raise ConfigError(f"{name}: expected class or model names as keys, got {V.show(k)}")
        out[k] = V.in_range(f"{name}.{k}", w, 0.0, 1e6)
    if sum(out.values()) <= 0:
        raise ConfigError(f"{name}: expected a positive total weight, got {V.show(value)}")
    return out


@dataclass(frozen=True)
class ParkingConfig:
    """Parking settings.

    occupancy_mean / occupancy_concentration : per lot (and per kerb line) the share of
        filled bays is drawn from Beta(mean * c, (1 - mean) * c); mean in [0, 1] (0 and 1:
        always empty / always full), c > 0 (larger = less spread between lots)
    back_in_share   : share of vehicles parked back-in (perpendicular and parallel bays;
                      angled bays are always entered nose-in), [0, 1]
    lateral_sigma_m : sigma of the sideways (and along-bay) offset in the bay, [0, 1] m
    angle_sigma_deg : sigma of the heading jitter, [0, 10] degrees; the jitter is a normal
                      truncated at +- angle_max_deg ((0, 10] degrees)
    mix             : class mix of ordinary lots and kerbs: {class or catalog model: weight};
                      a class spreads its weight over its models by catalog weight (equally
                      when those are all 0); only vehicles that fit a bay are drawn
    depot_mix       : the same for bays at least depot_bay_min_m long (bus and truck bays)
    layout          : bay layout of lots that carry none (OSM lots, meshes): bay size, angle,
                      aisle (scene/parking_layout.py LotLayout; default 2.5 x 5.0 m,
                      90 degrees, 6 m aisles)
    grid_m          : spacing of the vertical traces that find lots, (0.05, 5] m
    min_lot_m       : surfaces narrower than this (driveways, entrances) are no lot, m
    kerb_sides      : "both" kerbs of a street or "one" (the first found per stretch)
    kerb_bay_m      : length of a kerb bay (parallel parking), m
    kerb_offset_m   : vehicle centre from the kerb edge, m
    kerb_clear_m    : kept free before a junction and around driveways, m
    kerb_road_width_m : [min, max] carriageway width that gets kerb parking, m
    kerb_lines      : how many kerb lines to seed at most
    """

    occupancy_mean: float = 0.7
    occupancy_concentration: float = 12.0
    back_in_share: float = 0.25
    lateral_sigma_m: float = 0.15
    angle_sigma_deg: float = 2.0
    angle_max_deg: float = 2.8
    mix: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_MIX))
    depot_mix: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_DEPOT_MIX))
    depot_bay_min_m: float = 10.0
    layout: Mapping[str, Any] = field(default_factory=dict)
    grid_m: float = 1.0
    min_lot_m: float = 8.0
    kerb_sides: str = "both"
    kerb_bay_m: float = 6.0
    kerb_offset_m: float = 1.1
    kerb_clear_m: float = 5.0
    kerb_road_width_m: tuple[float, float] = (6.0, 12.0)
    kerb_lines: int = 200

    def __post_init__(self) -> None:
        p = "parking."
        s = object.__setattr__
        s(self, "occupancy_mean", V.in_range(p + "occupancy_mean", self.occupancy_mean, 0.0, 1.0))
        s(self, "occupancy_concentration", V.in_range(p + "occupancy_concentration",
                                                      self.occupancy_concentration, 0.0, 1e6, lo_open=True))
        s(self, "back_in_share", V.probability(p + "back_in_share", self.back_in_share))
        s(self, "lateral_sigma_m", V.in_range(p + "lateral_sigma_m", self.lateral_sigma_m, 0.0, 1.0))
        s(self, "angle_sigma_deg", V.in_range(p + "angle_sigma_deg", self.angle_sigma_deg, 0.0, 10.0))
        s(self, "angle_max_deg", V.in_range(p + "angle_max_deg", self.angle_max_deg, 0.0, 10.0, lo_open=True))
        s(self, "mix", _mix(p + "mix", self.mix))
        s(self, "depot_mix", _mix(p + "depot_mix", self.depot_mix))
        s(self, "depot_bay_min_m", V.in_range(p + "depot_bay_min_m", self.depot_bay_min_m, 0.0, 100.0))
        V.mapping(p + "layout", self.layout)
        s(self, "layout", dict(self.layout))
        self.lot_layout()  # validates
        s(self, "grid_m", V.in_range(p + "grid_m", self.grid_m, 0.05, 5.0))
        s(self, "min_lot_m", V.in_range(p + "min_lot_m", self.min_lot_m, 0.0, 1000.0))
        V.one_of(p + "kerb_sides", self.kerb_sides, ("both", "one"))
        s(self, "kerb_bay_m", V.in_range(p + "kerb_bay_m", self.kerb_bay_m, 2.0, 30.0))
        s(self, "kerb_offset_m", V.in_range(p + "kerb_offset_m", self.kerb_offset_m, 0.5, 5.0))
        s(self, "kerb_clear_m", V.in_range(p + "kerb_clear_m", self.kerb_clear_m, 0.0, 50.0))
        rw = V.sequence_of_numbers(p + "kerb_road_width_m", self.kerb_road_width_m, positive_only=True)
        if len(rw) != 2 or rw[0] > rw[1]:
            raise ConfigError(f"{p}kerb_road_width_m: expected [min, max] metres with min <= max, "
                              f"got {V.show(self.kerb_road_width_m)}")
        s(self, "kerb_road_width_m", tuple(rw))
        s(self, "kerb_lines", V.integer(p + "kerb_lines", self.kerb_lines, 0, 1_000_000))

    def lot_layout(self):
        """The default :class:`LotLayout` (lots that carry none)."""
        try:
            from ..scene.parking_layout import parse_layout  # lazy: --help imports this module

            return parse_layout(self.layout or None, "parking.layout")
        except SceneError as exc:
            raise ConfigError(str(exc)) from None

    def to_dict(self) -> dict:
        d = asdict(self)
        d["mix"], d["depot_mix"], d["layout"] = dict(self.mix), dict(self.depot_mix), dict(self.layout)
        d["kerb_road_width_m"] = list(self.kerb_road_width_m)
        return d


PARKING_KEYS = tuple(f.name for f in fields(ParkingConfig))


def parse_parking(value: Any, label) -> ParkingConfig:
    """The ``parking`` block (a mapping or null); ``label(path)`` names a field for errors
    (the scenario file or ``--set``)."""
    if value is None:
        return ParkingConfig()
    if not isinstance(value, Mapping):
        raise ConfigError(f"{label('parking')}: expected a mapping, got {V.show(value)}")
    unknown = sorted(str(k) for k in value if k not in PARKING_KEYS)
    if unknown:
        raise ConfigError(f"{label('parking.' + unknown[0])}: unknown key; expected one of "
                          f"{', '.join(PARKING_KEYS)}")
    try:
        return ParkingConfig(**dict(value))
    except ConfigError as exc:
        msg = str(exc)
        head, rest = msg.split(":", 1)[0], msg[len(msg.split(":", 1)[0]):]
        if not head.startswith("parking"):
            raise ConfigError(f"{label('parking')}: {msg}") from None
        parts = head.split(".")
        over = getattr(label, "overridden", set())
        for i in range(len(parts), 0, -1):
            pre = ".".join(parts[:i])
            if pre in over:
                tail = "." + ".".join(parts[i:]) if parts[i:] else ""
                raise ConfigError(f"{label(pre)}{tail}{rest}") from None
        raise ConfigError(f"{label(head)}{rest}") from None
