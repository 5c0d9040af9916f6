"""Vehicle model types: classes, body types, axes, colours, models and variants.

Pure value objects (frozen dataclasses) shared by the catalog parser
(:mod:`aerial_synth.vehicles.catalog`), the mesh builders (:mod:`.meshes`) and user-mesh
loading (:mod:`.user_mesh`); this module imports none of them, so there is no import cycle.

Vehicle frame (every mesh): metres, origin at the footprint centre on the ground,
+x forward, +y left, z up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ..errors import AssetError
from .bodies import CAR_PROFILES

__all__ = [
    "CLASSES",
    "BODY_TYPES",
    "AXES",
    "MESH_SUFFIXES",
    "VehicleModel",
    "VehicleColor",
    "VehicleVariant",
]

#: Detection classes, as in DOTA and EAGLE.
CLASSES: tuple[str, ...] = ("small-vehicle", "large-vehicle")

#: Procedural body types understood by :func:`aerial_synth.vehicles.build_mesh`.
BODY_TYPES: tuple[str, ...] = (
    "sport",
    "hatchback",
    "sedan",
    "suv",
    "pickup",
    "box_truck",
    "campervan",
    "city_bus",
    "school_bus",
    "coach",
    "delivery_van",
    "semi_trailer",
    # residential and farm vehicles (vehicles/towed.py)
    "tractor",
    "farm_trailer",
    "boat_trailer",
    "utility_trailer",
) + tuple(CAR_PROFILES)  # compact, estate, mpv, van, minibus (.bodies)

#: Axis names accepted for a user mesh's ``forward`` and ``up``.
AXES: dict[str, tuple[float, float, float]] = {
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "+z": (0.0, 0.0, 1.0),
    "-z": (0.0, 0.0, -1.0),
}

MESH_SUFFIXES: tuple[str, ...] = (".glb", ".gltf", ".obj")

# --------------------------------------------------------------------------- records
@dataclass(frozen=True)
class VehicleColor:
    """One paint colour.

    rgb    : 3 floats in [0, 1], linear-ish albedo (same scale as scene materials)
    weight : relative frequency (>= 0; normalised over the palette)
    """

    name: str
    rgb: tuple[float, float, float]
    weight: float = 1.0

    def __post_init__(self) -> None:
        rgb = tuple(float(c) for c in self.rgb)
        if len(rgb) != 3 or not all(0.0 <= c <= 1.0 for c in rgb):
            raise AssetError(
                f"colour {self.name!r}: rgb must be 3 floats in [0, 1], got {self.rgb}"
            )
        if not (self.weight >= 0.0 and math.isfinite(self.weight)):
            raise AssetError(f"colour {self.name!r}: weight must be >= 0, got {self.weight}")
        object.__setattr__(self, "rgb", rgb)
        object.__setattr__(self, "weight", float(self.weight))


@dataclass(frozen=True)
class VehicleModel:
    """One vehicle model.

    name        : unique in the catalog (e.g. ``"hatchback"``)
    pack        : asset pack number (1, 2 as in the thesis; 0 for user models by default)
    length_m, width_m, height_m : bounding-box size in metres (x, y, z of the vehicle frame)
    cls         : ``"small-vehicle"`` or ``"large-vehicle"``
    weight      : relative frequency (>= 0; normalised over the catalog)
    source      : ``"procedural:<body>"`` or ``"mesh:<path relative to the catalog>"``
    body        : procedural body type (one of :data:`BODY_TYPES`), ``""`` for user meshes
    mesh_path   : absolute path of a user mesh, or None
    scale       : user mesh: uniform scale applied to the file's units (to metres)
    forward, up : user mesh: the file's axes that become +x and +z (e.g. ``"-z"``, ``"+y"``)
    paint_material : user mesh: material name whose faces take the variant colour
    options     : procedural trim options built into the mesh (``sunroof``, ``roof_rack``,
                  ...; see :mod:`.catalog`); the model's name is then ``base+option``
    """

    name: str
    pack: int
    length_m: float
    width_m: float
    height_m: float
    cls: str
    weight: float = 1.0
    source: str = ""
    body: str = ""
    mesh_path: Path | None = None
    scale: float = 1.0
    forward: str = "+x"
    up: str = "+z"
    paint_material: str = ""
    options: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "options", tuple(self.options))
        for f in ("length_m", "width_m", "height_m"):
            v = getattr(self, f)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise AssetError(f"model {self.name!r}: {f} must be a number > 0, got {v!r}")
            object.__setattr__(self, f, float(v))
        if self.cls not in CLASSES:
            raise AssetError(
                f"model {self.name!r}: class must be one of {', '.join(CLASSES)}, got {self.cls!r}"
            )
        if not (math.isfinite(self.weight) and self.weight >= 0):
            raise AssetError(f"model {self.name!r}: weight must be >= 0, got {self.weight!r}")
        object.__setattr__(self, "weight", float(self.weight))
        if not self.source:
            src = f"procedural:{self.body}" if self.body else "mesh"
            object.__setattr__(self, "source", src)

    @property
    def base_name(self) -> str:
        """The catalog model this one derives from (its name without ``+option``)."""
        return self.name.split("+", 1)[0]

    @property
    def is_procedural(self) -> bool:
        return self.mesh_path is None

    @property
    def size_m(self) -> tuple[float, float, float]:
        """(length, width, height) in metres."""
        return (self.length_m, self.width_m, self.height_m)


@dataclass(frozen=True)
class VehicleVariant:
    """One model in one colour."""

    model: VehicleModel
    color: VehicleColor

    @property
    def name(self) -> str:
        return f"{self.model.name}/{self.color.name}"
