"""Placement records: where every vehicle stands. Pure data, JSON round-trip."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, fields
from functools import lru_cache

import numpy as np

from ..errors import PlacementError
from ..safe_input import load_json
from ..versions import versions

__all__ = ["PlacedVehicle", "Placement", "footprint_corners_xy", "with_lonlat"]


@dataclass(frozen=True)
class PlacedVehicle:
    """One placed vehicle.

    id          : instance id >= 1 (the renderer's instance buffer uses the same ids)
    x_m, y_m, z_m : footprint centre on the ground, metres, the scene's local frame (z up),
                  where ray casting and rendering happen
    x_orig_m, y_orig_m, z_orig_m : the same point in the scene file's original frame
                  (``Scene.to_original``: local + the scene's float64 origin; in the CRS
                  named by the placement's georeference when there is one); nan if unknown
    lon_deg, lat_deg : WGS84 longitude/latitude of that point when the scene has a CRS
                  (see :func:`with_lonlat`; written with 9 decimals, about 0.1 mm); nan if not
    heading_rad : 0 = +x (east), counter-clockwise, in [0, 2 pi)
    line_id     : traffic line (-1 for the random scenario)
    lane        : 0 = the line's own lane, 1 = the opposite lane of a double lane
    direction   : "forward" (seeded line) or "opposite" (its double lane) or "random"
    spacing_m   : centre-to-centre distance to the predecessor in its line (nan for the first)
    state       : "moving" (traffic) or "parked" (placement/parking.py)
    lot, kerb   : id of the parking lot or of the kerb line a parked vehicle stands in (-1 none)
    bay         : index of its bay in that lot or kerb line (-1 for moving vehicles)
    driveway    : id of the driveway, side pad or farm yard a parked vehicle stands in
                  (the scene's ``driveways`` hint, placement/driveways.py; -1 none)
    """

    id: int
    model: str
    color: str
    cls: str
    length_m: float
    width_m: float
    height_m: float
    x_m: float
    y_m: float
    z_m: float
    heading_rad: float
    line_id: int = -1
    lane: int = 0
    direction: str = "forward"
    spacing_m: float = float("nan")
    x_orig_m: float = float("nan")
    y_orig_m: float = float("nan")
    z_orig_m: float = float("nan")
    lon_deg: float = float("nan")
    lat_deg: float = float("nan")
    state: str = "moving"
    lot: int = -1
    kerb: int = -1
    bay: int = -1
    driveway: int = -1

    def to_dict(self) -> dict:
        # every field is a scalar: read them straight (dataclasses.asdict deep-copies each
        # value; with ~60 vehicles per image that was 12 ms of every exported image)
        d = {k: getattr(self, k) for k in _vehicle_fields()}
        if d["driveway"] < 0:  # only driveway vehicles carry it (other records keep their bytes)
            del d["driveway"]
        for k, v in d.items():
            if isinstance(v, float):
                d[k] = None if not math.isfinite(v) else round(v, 9 if k in _DEGREES else 6)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "PlacedVehicle":
        names = {f.name for f in fields(cls)}
        kw = {k: v for k, v in d.items() if k in names}
        for k in ("spacing_m", "x_orig_m", "y_orig_m", "z_orig_m", "lon_deg", "lat_deg"):
            if kw.get(k) is None:
                kw[k] = float("nan")
        return cls(**kw)

    def corners_xy(self, gap_m: float = 0.0) -> np.ndarray:
        """(4, 2) footprint corners, metres, scene (local) frame: front-left, front-right,
        rear-right, rear-left.

        ``gap_m`` has the meaning of the scenario's ``gap_m``, the clearance between two
        footprints: the rectangle is grown by ``gap_m / 2`` on every side, so the grown
        rectangles of two vehicles are disjoint exactly when their bare footprints are at
        least ``gap_m`` apart. A negative value shrinks the rectangle the same way.
        """
        return footprint_corners_xy(
            self.x_m, self.y_m, self.heading_rad, self.length_m + gap_m, self.width_m + gap_m
        )


_DEGREES = ("lon_deg", "lat_deg")


@lru_cache(maxsize=1)
def _vehicle_fields() -> tuple[str, ...]:
    return tuple(f.name for f in fields(PlacedVehicle))


def with_lonlat(vehicles: list, crs: str | None) -> list:
    """The vehicles with ``lon_deg``/``lat_deg`` from their original-frame position in
    ``crs`` (pyproj, always x = easting / longitude first). Unchanged when crs is None."""
    if not crs or not vehicles:
        return list(vehicles)
    import dataclasses

    import pyproj

    xy = np.array([[v.x_orig_m, v.y_orig_m] for v in vehicles], dtype=np.float64)
    try:
        tr = pyproj.Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
    except pyproj.exceptions.CRSError:  # a CRS pyproj does not know: no lon/lat
        return list(vehicles)
    lon, lat = (np.where(np.isfinite(a), a, np.nan) for a in tr.transform(xy[:, 0], xy[:, 1]))
    return [dataclasses.replace(v, lon_deg=float(a), lat_deg=float(b))
            for v, a, b in zip(vehicles, np.atleast_1d(lon), np.atleast_1d(lat))]


def footprint_corners_xy(x, y, heading_rad, length_m, width_m) -> np.ndarray:
    """Rotated-rectangle corners; scalar inputs give (4, 2), arrays of n give (n, 4, 2).

    Order: front-left, front-right, rear-right, rear-left (vehicle frame +x forward, +y left).
    """
    x, y, h, ln, w = np.broadcast_arrays(*map(np.asarray, (x, y, heading_rad, length_m, width_m)))
    c, s = np.cos(h), np.sin(h)
    local = np.array([[0.5, 0.5], [0.5, -0.5], [-0.5, -0.5], [-0.5, 0.5]])  # (4, 2) in (l, w)
    lx = local[:, 0] * ln[..., None]
    ly = local[:, 1] * w[..., None]
    wx = x[..., None] + c[..., None] * lx - s[..., None] * ly
    wy = y[..., None] + s[..., None] * lx + c[..., None] * ly
    return np.stack([wx, wy], axis=-1)


@dataclass
class Placement:
    """A placement: scene, scenario, parameters, seed and the vehicles.

    georeference : ``Scene.georeference()`` of the scene it was placed on: ``{"origin":
                   [x, y, z], "crs": str|None}``, original = local + origin (None if unknown)
    """

    scene: str
    scenario: str
    seed: int | None
    parameters: dict = field(default_factory=dict)
    vehicles: list[PlacedVehicle] = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    georeference: dict | None = None
    #: wall-clock figures of the run that made it; never serialised (they differ per run)
    timing: dict = field(default_factory=dict, compare=False)

    def to_dict(self) -> dict:
        return {
            "scene": self.scene,
            "scenario": self.scenario,
            "seed": self.seed,
            "parameters": self.parameters,
            "stats": self.stats,
            "georeference": self.georeference,
            "vehicles": [v.to_dict() for v in self.vehicles],
        }

    def to_json(self) -> str:
        """``placement.json``: :meth:`to_dict` plus the versions that produced it."""
        return json.dumps({**self.to_dict(), "versions": versions()}, indent=2, sort_keys=True) + "\n"

    @classmethod
    def from_dict(cls, d: dict) -> "Placement":
        return cls(
            scene=d["scene"],
            scenario=d["scenario"],
            seed=d.get("seed"),
            parameters=d.get("parameters", {}),
            stats=d.get("stats", {}),
            georeference=d.get("georeference"),
            vehicles=[PlacedVehicle.from_dict(v) for v in d.get("vehicles", [])],
        )

    @classmethod
    def from_json(cls, text: str) -> "Placement":
        return cls.from_dict(load_json(text, "placement JSON", PlacementError))

    def by_id(self) -> dict[int, PlacedVehicle]:
        return {v.id: v for v in self.vehicles}
