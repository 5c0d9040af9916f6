"""Traffic scenarios: traffic lines with double lanes (thesis §3.2.3) and the random baseline.

The engine only probes the RayScene with vertical traces (see :mod:`.linetrace`); road
polygons a generator may know are never read here. Its state and per-vehicle steps are
:mod:`.traffic_engine`, its lines :mod:`.traffic_lines`; this module is the entry point. The lines advance in batched lock-step waves
whose result depends only on the seed (see :mod:`.traffic_lines`).
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from .. import validators as V
from ..errors import PlacementError
from ..vehicles import load_catalog
from .config import ScenarioConfig, load_scenario
from .driveways import place_driveways
from .model import Placement, with_lonlat
from .parking import place_parking
from .parking_config import PARKING_KINDS
from .traffic_engine import lane_rule
from .traffic_lines import TrafficEngine

__all__ = ["place", "PlacementWarning", "lane_rule"]


class PlacementWarning(UserWarning):
    """Fewer vehicles than asked for fit on the roads."""


def place(
    rayscene,
    scenario: str | ScenarioConfig = "jam",
    rng: np.random.Generator | None = None,
    n_vehicles: int | None = None,
    n_lines: int | None = None,
    catalog=None,
    overrides: dict | None = None,
    seed: int | None = None,
    scene_name: str | None = None,
    obstacles=None,
    region=None,
) -> Placement:
    """Place vehicles on the roads of ``rayscene`` for one traffic scenario.

    scenario  : a bundled name (jam, normal, sparse, random), a YAML path or a ScenarioConfig
    rng       : the random generator; if None, ``np.random.default_rng(seed)``
    n_vehicles / n_lines : how much to place (at most one; default from the scenario).
                For lines scenarios n_lines counts seeded lines; opposite lanes come on top.
    catalog   : vehicle catalog (default: the bundled one)
    obstacles : vehicles already standing (PlacedVehicle, e.g. parked ones): footprints keep
                gap_m from them (the ``mixed`` scenario, placement/parking.py)
    region    : tiled placement (placement/tiled.py), traffic scenarios: ``((x0, y0, x1, y1),
                owns)``: line seeds are drawn inside the rectangle only, and only vehicles
                whose centres ``owns(xy) -> (n,) bool`` accepts are placed (a line ends
                at the border: reason "tile_border"); the traces still see the whole scene
    Returns a :class:`Placement`. If the roads hold fewer vehicles than asked for, it places
    what fits, records the shortfall in ``stats`` and emits a :class:`PlacementWarning`.
    """
    if n_vehicles is not None and n_lines is not None:
        raise PlacementError("give either a vehicle count or a line count, not both")

    n_vehicles = None if n_vehicles is None else V.integer("--vehicles", n_vehicles, 1, error=PlacementError)
    n_lines = None if n_lines is None else V.integer("--lines", n_lines, 1, error=PlacementError)
    seed = None if seed is None else V.integer("--seed", seed, 0, error=PlacementError)
    cfg = load_scenario(scenario, overrides)
    if rng is None:
        rng = np.random.default_rng(seed)
    if catalog is None:
        catalog = load_catalog()
    if cfg.kind == "driveways":  # residential and farm sites, then kerbs and traffic
        return place_driveways(rayscene, cfg, rng, catalog, seed=seed, scene_name=scene_name,
                               n_vehicles=n_vehicles, n_lines=n_lines, place_traffic=place)
    if cfg.kind in PARKING_KINDS:  # parking, street-parking, mixed: placement/parking.py

        return place_parking(rayscene, cfg, rng, catalog, seed=seed, scene_name=scene_name,
                             n_vehicles=n_vehicles, n_lines=n_lines, place_traffic=place)
    t0 = time.perf_counter()
    eng = TrafficEngine(rayscene, cfg, rng, catalog, region=region)
    for v in obstacles or ():
        eng.index.add(eng.index.polygon(v.x_m, v.y_m, v.heading_rad, v.length_m, v.width_m), (v.x_m, v.y_m))
    if cfg.kind == "random":
        n = n_vehicles or cfg.vehicles or (n_lines * 30 if n_lines else 400)
        eng.run_random(int(n))
        asked = int(n)
    else:
        if n_vehicles is None and n_lines is None:
            n_vehicles, n_lines = cfg.vehicles, (cfg.lines if cfg.vehicles is None else None)
        eng.run_lines(n_vehicles, n_lines)
        asked = n_vehicles
    if not eng.road_seen:
        raise PlacementError(
            f"scene {rayscene.scene.name!r}: {eng.seeds_tried} vertical traces over its extent found no "
            f"road (labels {sorted(rayscene.label_config.road)})"
        )
    elapsed = time.perf_counter() - t0
    stats = _line_stats(eng, asked)
    timing = {"seconds": elapsed, "vehicles_per_s": len(eng.vehicles) / elapsed if elapsed else 0.0,
              "rays_per_s": eng.prober.n_rays / elapsed if elapsed else 0.0}
    placement = Placement(
        scene=scene_name or rayscene.scene.name,
        scenario=cfg.name,
        seed=seed,
        parameters=cfg.to_dict(),
        vehicles=with_lonlat(eng.vehicles, rayscene.scene.crs),  # lon/lat where the CRS is known
        stats=stats,
        timing=timing,
        georeference=rayscene.scene.georeference(),
    )
    if asked is not None and eng.counted < asked:
        msg = (f"the roads of {placement.scene!r} held {eng.counted} of the {asked} vehicles asked "
               f"for ({cfg.name})")
        stats["shortfall"] = asked - eng.counted
        warnings.warn(msg, PlacementWarning, stacklevel=2)
    return placement


def _line_stats(eng: TrafficEngine, asked: int | None) -> dict:
    """``Placement.stats`` of a traffic placement: counts, why lines ended, the line table,
    spacing (metres), seeding and ray counts."""
    spac = np.array([v.spacing_m for v in eng.vehicles if np.isfinite(v.spacing_m)])
    reasons: dict[str, int] = {}
    for ln in eng.lines:
        reasons[ln.reason or "complete"] = reasons.get(ln.reason or "complete", 0) + 1
    return {
        "vehicles": len(eng.vehicles),
        "requested_vehicles": asked,
        "lines": sum(1 for ln in eng.lines if ln.lane == 0 and ln.lane_index == 0),
        "opposite_lanes": sum(1 for ln in eng.lines if ln.lane == 1 and ln.lane_index == 0),
        "inner_lanes": sum(1 for ln in eng.lines if ln.lane_index > 0),
        "line_end_reasons": dict(sorted(reasons.items())),
        # per line: [line id, lane, why it ended, vehicles]
        "line_table": [[ln.line_id, ln.lane, ln.reason or "complete", len(ln.placed)] for ln in eng.lines],
        "spacing_m": {
            "n": int(len(spac)),
            "mean": round(float(spac.mean()), 4) if len(spac) else None,
            "sd": round(float(spac.std(ddof=1)), 4) if len(spac) > 1 else None,
            "min": round(float(spac.min()), 4) if len(spac) else None,
            "max": round(float(spac.max()), 4) if len(spac) else None,
        },
        "seed_traces": int(eng.seeds_tried),
        "stopped_full": bool(eng.stopped_full),
        "seed_failures": dict(sorted(eng.start_failures.items())),
        "rays": int(eng.prober.n_rays),
        "casts": int(eng.prober.n_casts),
    }
