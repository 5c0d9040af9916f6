"""Line-trace placement engine and traffic scenarios (thesis §3.2)."""

from __future__ import annotations

from .config import SCENARIOS, ScenarioConfig, list_scenarios, load_scenario
from .model import PlacedVehicle, Placement, footprint_corners_xy
from .spacing import SpacingSampler

__all__ = [
    "SCENARIOS",
    "ScenarioConfig",
    "SpacingSampler",
    "PlacedVehicle",
    "Placement",
    "footprint_corners_xy",
    "list_scenarios",
    "load_scenario",
    "place",
    "validate_placement",
]


def place(*args, **kwargs):
    """See :func:`aerial_synth.placement.traffic.place`."""
    from .traffic import place as _place  # lazy: the line-trace engine; --help imports this package

    return _place(*args, **kwargs)


def validate_placement(*args, **kwargs):
    """See :func:`aerial_synth.placement.footprints.validate_placement`."""
    from .footprints import validate_placement as _v  # lazy: as place()

    return _v(*args, **kwargs)
