"""Scene model: named, labelled triangle meshes in a z-up metric world frame.

World frame: metres, right-handed, x east, y north, z up.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Mapping

import numpy as np

from ..errors import ConfigError
from ..validators import known_keys, mapping, show
from .scene_hints import NO_HINTS, SceneHints

__all__ = [
    "LABELS",
    "LABEL_IDS",
    "MATERIALS",
    "MATERIAL_IDS",
    "DEFAULT_MATERIAL_FOR_LABEL",
    "DEFAULT_COLOR_FOR_MATERIAL",
    "LabelConfig",
    "SceneObject",
    "RoadTruth",
    "SceneTruth",
    "Scene",
    "label_id",
]

#: Semantic labels. The index is the semantic id written by the renderer (0 = nothing hit).
LABELS: tuple[str, ...] = (
    "unknown",
    "road",
    "lane_marking",
    "sidewalk",
    "parking",
    "ground",
    "water",
    "building",
    "tree",
    "trunk",
    "pole",
    "vehicle",
    "parking_marking",  # painted bay lines on parking (last: earlier ids keep their values)
)
LABEL_IDS: dict[str, int] = {name: i for i, name in enumerate(LABELS)}

#: Surface materials the shader knows. Scene objects name one; unknown names are refused.
MATERIALS: tuple[str, ...] = (
    "default",
    "asphalt",
    "marking",
    "concrete",
    "paving",
    "grass",
    "soil",
    "water",
    "roof",
    "wall",
    "foliage",
    "bark",
    "metal",
    "paint",
    "glass",
    "tyre",
    "trim",
    "cargo",
    "light_front",
    "light_rear",
    # appended (ids above stay stable): roof coverings and lane wear
    "roof_gravel",
    "roof_tiles",
    "roof_metal",
    "track",
)
MATERIAL_IDS: dict[str, int] = {name: i for i, name in enumerate(MATERIALS)}

DEFAULT_MATERIAL_FOR_LABEL: dict[str, str] = {
    "unknown": "default",
    "road": "asphalt",
    "lane_marking": "marking",
    "sidewalk": "paving",
    "parking": "asphalt",
    "ground": "grass",
    "water": "water",
    "building": "roof",
    "tree": "foliage",
    "trunk": "bark",
    "pole": "metal",
    "vehicle": "paint",
    "parking_marking": "marking",
}

#: Base albedo (linear-ish RGB in [0, 1]) per material, used when an object names no colour.
DEFAULT_COLOR_FOR_MATERIAL: dict[str, tuple[float, float, float]] = {
    "default": (0.5, 0.5, 0.5),
    "asphalt": (0.24, 0.24, 0.25),
    "marking": (0.85, 0.85, 0.82),
    "concrete": (0.62, 0.61, 0.58),
    "paving": (0.58, 0.55, 0.52),
    # a green lawn (luma 0.167; the frame's ground_albedo gain x 0.45-0.85 gives 0.075-0.14):
    # green vegetation reflects ~0.04 (blue), ~0.08-0.12 (green) and ~0.04-0.06 (red) of
    # visible light (USGS spectral library, lawn grass; broadband albedo ~0.25 only with
    # the near infrared), so a lawn's visible luma is ~0.08-0.12. Was (0.27, 0.40, 0.17),
    # luma 0.33, which made green lawns 0.15-0.28, as bright as dry grass. Dry lawns come
    # from vegetation_dryness, which mixes towards the straw albedo render.shading._DRY_RGB
    # (luma 0.36, x the same gain: 0.16-0.31 at dryness 1).
    "grass": (0.135, 0.20, 0.085),
    "soil": (0.42, 0.34, 0.24),
    "water": (0.10, 0.20, 0.25),
    "roof": (0.55, 0.30, 0.24),
    "wall": (0.75, 0.72, 0.66),
    # a broadleaf canopy's visible reflectance (luma 0.076; sources and the species
    # colours in scene/procedural/trees.py SPECIES_COLORS). Was (0.16, 0.32, 0.12), luma
    # 0.25: crowns as bright as the roads
    "foliage": (0.052, 0.095, 0.038),
    "bark": (0.30, 0.22, 0.15),
    "metal": (0.45, 0.46, 0.48),
    "paint": (0.7, 0.7, 0.7),
    "glass": (0.05, 0.07, 0.09),
    "tyre": (0.03, 0.03, 0.03),
    "trim": (0.10, 0.10, 0.10),
    "cargo": (0.85, 0.85, 0.83),
    "light_front": (0.90, 0.90, 0.85),
    "light_rear": (0.60, 0.05, 0.05),
    "roof_gravel": (0.52, 0.50, 0.47),
    "roof_tiles": (0.50, 0.25, 0.18),
    "roof_metal": (0.58, 0.60, 0.62),
    "track": (0.20, 0.20, 0.21),
}


def label_id(name: str) -> int:
    """Semantic id of a label name; raises :class:`ConfigError` listing the valid names."""
    try:
        return LABEL_IDS[name]
    except KeyError:
        raise ConfigError(
            f"unknown label {name!r}: expected one of {', '.join(LABELS[1:])}"
        ) from None


def _label_set(field_name: str, names: Iterable[str]) -> frozenset[str]:
    out = frozenset(names)
    bad = sorted(n for n in out if n not in LABEL_IDS)
    if bad:
        raise ConfigError(
            f"label config field {field_name!r}: unknown label(s) {bad}; expected names from "
            f"{', '.join(LABELS[1:])}"
        )
    return out


@dataclass(frozen=True)
class LabelConfig:
    """Which labels mean what while probing. Configuration, not code.

    road:      labels that count as "road" for edge probing (line traces march until the hit
               is no longer one of these). Lane markings are painted road, so they count.
    drivable:  labels a vehicle footprint may stand on.
    obstacles: labels that block a footprint when hit from above.
    ignore:    labels traces pass through while probing (the thesis's "actors to ignore":
               tree crowns that overhang the road).
    """

    road: frozenset[str] = frozenset({"road", "lane_marking"})
    drivable: frozenset[str] = frozenset({"road", "lane_marking", "parking", "parking_marking"})
    obstacles: frozenset[str] = frozenset(
        {"building", "trunk", "pole", "water", "vehicle", "sidewalk", "ground"}
    )
    ignore: frozenset[str] = frozenset({"tree"})

    def __post_init__(self) -> None:
        for name in ("road", "drivable", "obstacles", "ignore"):
            object.__setattr__(self, name, _label_set(name, getattr(self, name)))
        both = self.drivable & self.obstacles
        if both:
            raise ConfigError(f"label config: labels {sorted(both)} are both drivable and obstacles")

    @classmethod
    def from_mapping(cls, data: Mapping | None) -> "LabelConfig":
        """Build from a YAML mapping with optional keys road/drivable/obstacles/ignore, each
        a list of label names (null = empty). Raises ConfigError naming the field."""
        if data is None:
            return cls()
        mapping("label_config", data)
        if not data:
            return cls()
        keys = ("road", "drivable", "obstacles", "ignore")
        known_keys("label_config", data, keys)
        kw = {}
        for k, v in data.items():
            if v is None:
                v = []
            if not isinstance(v, (list, tuple)) or not all(isinstance(n, str) for n in v):
                raise ConfigError(
                    f"label_config.{k}: expected a list of label names, got {show(v)}"
                )
            kw[k] = frozenset(v)
        return cls(**kw)

    def ids(self, which: str) -> np.ndarray:
        """Semantic ids of one of the sets, as a sorted int array."""
        return np.array(sorted(LABEL_IDS[n] for n in getattr(self, which)), dtype=np.int16)

    def to_dict(self) -> dict:
        return {k: sorted(getattr(self, k)) for k in ("road", "drivable", "obstacles", "ignore")}


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One named, labelled triangle mesh.

    vertices : (n, 3) float64, metres, world frame (z up)
    faces    : (m, 3) int64 vertex indices, counter-clockwise seen from outside
    material : a name from :data:`MATERIALS`
    color    : base albedo RGB in [0, 1]
    """

    name: str
    label: str
    vertices: np.ndarray
    faces: np.ndarray
    material: str = ""
    color: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        label_id(self.label)
        v = np.ascontiguousarray(self.vertices, dtype=np.float64)
        f = np.ascontiguousarray(self.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ConfigError(f"object {self.name!r}: vertices must be (n, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3:
            raise ConfigError(f"object {self.name!r}: faces must be (m, 3), got {f.shape}")
        if not np.isfinite(v).all():
            i = int(np.argmax(~np.isfinite(v).all(axis=1)))
            raise ConfigError(
                f"object {self.name!r}: expected finite vertex coordinates, got "
                f"{v[i].tolist()} at vertex {i}"
            )
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ConfigError(f"object {self.name!r}: face index outside 0..{len(v) - 1}")
        mat = self.material or DEFAULT_MATERIAL_FOR_LABEL[self.label]
        if mat not in MATERIAL_IDS:
            raise ConfigError(
                f"object {self.name!r}: unknown material {mat!r}; expected one of "
                f"{', '.join(MATERIALS)}"
            )
        col = self.color if self.color is not None else DEFAULT_COLOR_FOR_MATERIAL[mat]
        col = tuple(float(c) for c in col)
        if len(col) != 3 or not all(0.0 <= c <= 1.0 for c in col):
            raise ConfigError(f"object {self.name!r}: color must be 3 floats in [0, 1], got {col}")
        v.setflags(write=False)
        f.setflags(write=False)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        object.__setattr__(self, "material", mat)
        object.__setattr__(self, "color", col)

    @property
    def n_triangles(self) -> int:
        return int(len(self.faces))


@dataclass(frozen=True)
class RoadTruth:
    """Ground truth of one road (validation only; placement never reads it).

    centerline : shapely LineString, metres, world xy
    width_m    : carriageway width
    oneway     : True for one carriageway of a dual carriageway (traffic follows the line's
                 direction), False for two-way roads.
    """

    centerline: object
    width_m: float
    oneway: bool = False
    name: str = ""


@dataclass(frozen=True)
class SceneTruth:
    """What a procedural generator knows. For tests and the validator only."""

    road_area: object  # shapely (Multi)Polygon: union of road surfaces (incl. junctions)
    roads: tuple[RoadTruth, ...] = ()
    parking_area: object | None = None

    def nearest_road(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tangent heading (rad, along the line's direction) and index of the nearest road
        centre line for each point. xy: (n, 2) metres. Returns ((n,), (n,))."""
        import shapely

        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        pts = shapely.points(xy)
        lines = [r.centerline for r in self.roads]
        dist = np.stack([shapely.distance(line, pts) for line in lines], axis=1)
        idx = np.argmin(dist, axis=1)
        heading = np.empty(len(xy))
        for k, line in enumerate(lines):
            sel = idx == k
            if not sel.any():
                continue
            s = shapely.line_locate_point(line, pts[sel])
            a = shapely.get_coordinates(shapely.line_interpolate_point(line, np.maximum(s - 0.5, 0)))
            b = shapely.get_coordinates(
                shapely.line_interpolate_point(line, np.minimum(s + 0.5, line.length))
            )
            d = b - a
            heading[sel] = np.arctan2(d[:, 1], d[:, 0])
        return heading, idx


@dataclass
class Scene:
    """A labelled scene: a list of :class:`SceneObject` plus provenance.

    truth is set by procedural generators (road polygons / centre lines) for validation only.

    Georeference: vertices are in a *local* metric frame near the origin (float32-safe for ray
    casting). ``origin`` is the float64 offset (metres) of that frame in the source file's frame
    (or in ``crs``): ``original_xyz = local_xyz + origin``. ``crs`` names the source CRS when
    known (e.g. ``"EPSG:32632"``), else None.
    """

    name: str
    objects: list[SceneObject]
    source: str = ""
    truth: SceneTruth | None = None
    label_config: LabelConfig = field(default_factory=LabelConfig)
    meta: dict = field(default_factory=dict)
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    crs: str | None = None
    hints: SceneHints = NO_HINTS

    def to_original(self, xyz) -> np.ndarray:
        """Local scene coordinates (n, 2|3) metres -> the source frame (float64)."""
        a = np.asarray(xyz, dtype=np.float64)
        o = np.asarray(self.origin, dtype=np.float64)[: a.shape[-1]]
        return a + o

    def georeference(self) -> dict:
        """``{"origin": [x, y, z], "crs": str|None}`` for metadata files."""
        return {"origin": [float(c) for c in self.origin], "crs": self.crs}

    @property
    def n_triangles(self) -> int:
        return sum(o.n_triangles for o in self.objects)

    def labels_present(self) -> set[str]:
        return {o.label for o in self.objects}

    def bounds(self) -> np.ndarray:
        """(2, 3) float: [[xmin, ymin, zmin], [xmax, ymax, zmax]] in metres."""
        if not self.objects:
            return np.zeros((2, 3))
        lo = np.min([o.vertices.min(axis=0) for o in self.objects if len(o.vertices)], axis=0)
        hi = np.max([o.vertices.max(axis=0) for o in self.objects if len(o.vertices)], axis=0)
        return np.stack([lo, hi])

    def vertex_hash(self, decimals: int | None = None) -> str:
        """SHA-256 over names, labels, materials, vertices and faces (for determinism checks).

        ``decimals``: hash the vertices rounded to that many decimals of a metre (6: a
        micrometre) instead of their exact bits. Two runs of one install agree bit for bit.
        Across machines the procedural generators snap their output to a power-of-two grid
        (:data:`aerial_synth.scene.build.GRID_M`) and avoid CPU-dispatched BLAS calls, so the
        hash normally agrees too; the tolerant cross-machine check is
        :func:`aerial_synth.scene.fingerprint.scene_fingerprint` (docs/portability.md).
        Pinned hashes use ``decimals=6`` and are machine-specific (``lock_exact``).
        """
        import hashlib

        h = hashlib.sha256()
        for o in self.objects:
            h.update(o.name.encode())
            h.update(o.label.encode())
            h.update(o.material.encode())
            v = np.ascontiguousarray(o.vertices)
            if decimals is not None:
                v = np.round(v.astype(np.float64), decimals) + 0.0  # -0.0 and 0.0 alike
            h.update(v.tobytes())
            h.update(np.ascontiguousarray(o.faces).tobytes())
        return h.hexdigest()
