"""Typed scene hints: what a scene tells placement beyond its geometry.

A :class:`SceneHints` travels on :attr:`Scene.hints <aerial_synth.scene.model.Scene.hints>`
(never in ``Scene.meta``). It holds:

- ``roads``     : :class:`~aerial_synth.scene.hints.RoadHints` (OSM driving directions) or None;
- ``driveways`` : :class:`DrivewayHint` per driveway, side pad or farm yard (procedural
                  residential/rural scenes, OSM ``service=driveway``);
- ``lots``      : :class:`LotHint` per painted lot of a procedural spec (its rectangle and
                  bay layout);
- ``spaces``    : mapped parking spaces (OSM ``amenity=parking_space``), one (k, 2) ring each;
- ``kerbs``     : :class:`KerbHint` per mapped road with kerb-parking tags;
- ``negatives`` : :class:`NegativesHint`, the unlabelled hard negatives a scene holds.

Every record checks its fields when built; :meth:`from_dict` turns a plain mapping into a
record and raises :class:`~aerial_synth.errors.SceneError` naming the field, what was
expected and what arrived.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..errors import SceneError
from .hints import RoadHints

__all__ = ["DrivewayHint", "LotHint", "KerbHint", "NegativesHint", "SceneHints", "NO_HINTS"]


def _fail(where: str, name: str, expected: str, got: Any):
    raise SceneError(f"{where}: field {name!r}: expected {expected}, got {got!r}")


def _num(where: str, name: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not np.isfinite(v):
        _fail(where, name, "a finite number", v)
    return float(v)


def _xy(where: str, name: str, v: Any) -> tuple[float, float]:
    if not isinstance(v, (list, tuple, np.ndarray)) or len(v) != 2:
        _fail(where, name, "an [x, y] pair", v)
    return (_num(where, name, v[0]), _num(where, name, v[1]))


def _weights(where: str, name: str, v: Any) -> tuple:
    if not isinstance(v, Mapping) and not isinstance(v, tuple):
        _fail(where, name, "a mapping name -> number", v)
    items = tuple(v.items()) if isinstance(v, Mapping) else v
    for k, w in items:
        if not isinstance(k, str):
            _fail(where, name, "string keys", k)
        _num(where, f"{name}.{k}", w)
    return items


def _build(cls, where: str, **kw):
    """cls(**kw), with ``where`` before any error message."""
    try:
        return cls(**kw)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None


def _mapping(where: str, d: Any) -> Mapping:
    if not isinstance(d, Mapping):
        raise SceneError(f"{where}: expected a mapping, got {type(d).__name__}")
    return d


@dataclass(frozen=True)
class DrivewayHint:
    """One parking site off the street: a driveway, a side pad or a farm yard.

    id         : site id, recorded with the vehicles parked on it
    kind       : ``driveway``, ``pad`` or ``yard``
    center_xy  : rectangle centre, metres, local scene frame
    axis_deg   : direction of the long side, degrees from +x
    long_m, short_m : usable rectangle
    bay_m      : (long, short) size of one bay
    occupancy  : fraction of bays taken
    mix        : ((class, weight), ...) of the vehicles parked there
    labels     : scene labels its vehicles may stand on (None: parking and its markings)
    osm_id     : source way (0 if none)
    """

    id: int
    kind: str
    center_xy: tuple[float, float]
    axis_deg: float
    long_m: float
    short_m: float
    bay_m: tuple[float, float]
    occupancy: float = 0.6
    mix: tuple = (("small-vehicle", 1.0),)
    labels: tuple[str, ...] | None = None
    osm_id: int = 0

    def __post_init__(self) -> None:
        w = f"driveway hint {self.id}"
        if isinstance(self.id, bool) or not isinstance(self.id, (int, np.integer)):
            _fail(w, "id", "an integer", self.id)
        if self.kind not in ("driveway", "pad", "yard"):
            _fail(w, "kind", "driveway, pad or yard", self.kind)
        object.__setattr__(self, "center_xy", _xy(w, "center_xy", self.center_xy))
        object.__setattr__(self, "bay_m", _xy(w, "bay_m", self.bay_m))
        for name in ("axis_deg", "long_m", "short_m", "occupancy"):
            object.__setattr__(self, name, _num(w, name, getattr(self, name)))
        if not 0.0 <= self.occupancy <= 1.0:
            _fail(w, "occupancy", "a fraction in [0, 1]", self.occupancy)
        object.__setattr__(self, "mix", _weights(w, "mix", self.mix))
        if self.labels is not None:
            if not isinstance(self.labels, (list, tuple)) or not all(isinstance(s, str) for s in self.labels):
                _fail(w, "labels", "a list of label names", self.labels)
            object.__setattr__(self, "labels", tuple(self.labels))

    @classmethod
    def from_dict(cls, d: Mapping, where: str = "driveway hint") -> DrivewayHint:
        d = _mapping(where, d)
        try:
            return _build(cls, where, id=d["id"], kind=d.get("kind", "driveway"), center_xy=d["center_xy"],
                       axis_deg=d["axis_deg"], long_m=d["long_m"], short_m=d["short_m"],
                       bay_m=d["bay_m"], occupancy=d.get("occupancy", 0.6),
                       mix=d.get("mix") or {"small-vehicle": 1.0}, labels=d.get("labels"),
                       osm_id=int(d.get("osm_id", 0)))
        except KeyError as exc:
            raise SceneError(f"{where}: field {exc.args[0]!r}: expected it, got nothing") from None

    def mix_dict(self) -> dict:
        return dict(self.mix)


@dataclass(frozen=True)
class LotHint:
    """One painted parking lot of a procedural spec.

    id        : lot number in the spec
    center_xy : rectangle centre; row_deg : direction of the bay rows, degrees from +x
    long_m, short_m : the lot rectangle
    layout    : ((key, value), ...) of a :class:`~aerial_synth.placement.lots.LotLayout`
    bays      : number of bays painted
    """

    id: int
    center_xy: tuple[float, float]
    row_deg: float
    long_m: float
    short_m: float
    layout: tuple
    bays: int = 0

    def __post_init__(self) -> None:
        w = f"lot hint {self.id}"
        object.__setattr__(self, "center_xy", _xy(w, "center_xy", self.center_xy))
        for name in ("row_deg", "long_m", "short_m"):
            object.__setattr__(self, name, _num(w, name, getattr(self, name)))
        if isinstance(self.layout, Mapping):
            object.__setattr__(self, "layout", tuple(self.layout.items()))
        if not isinstance(self.layout, tuple) or not all(isinstance(k, str) for k, _ in self.layout):
            _fail(w, "layout", "a mapping of layout fields", self.layout)

    @classmethod
    def from_dict(cls, d: Mapping, where: str = "lot hint") -> LotHint:
        d = _mapping(where, d)
        try:
            return _build(cls, where, id=d["id"], center_xy=d["center_xy"], row_deg=d["row_deg"], long_m=d["long_m"],
                       short_m=d["short_m"], layout=d["layout"], bays=int(d.get("bays", 0)))
        except KeyError as exc:
            raise SceneError(f"{where}: field {exc.args[0]!r}: expected it, got nothing") from None

    def layout_dict(self) -> dict:
        return dict(self.layout)


@dataclass(frozen=True, eq=False)
class KerbHint:
    """Kerb-parking tags of one mapped road: its centre line (k, 2), width and whether each
    side allows parking (None: not tagged)."""

    coords: np.ndarray
    width_m: float = 6.0
    left: bool | None = None
    right: bool | None = None

    def __post_init__(self) -> None:
        c = np.asarray(self.coords, dtype=np.float64)
        if c.ndim != 2 or c.shape[1] != 2 or len(c) < 2 or not np.isfinite(c).all():
            _fail("kerb hint", "coords", "(k >= 2, 2) finite coordinates", f"shape {c.shape}")
        object.__setattr__(self, "coords", c)
        object.__setattr__(self, "width_m", _num("kerb hint", "width_m", self.width_m))
        for side in ("left", "right"):
            v = getattr(self, side)
            if v is not None and not isinstance(v, (bool, np.bool_)):
                _fail("kerb hint", side, "true, false or null", v)

    @classmethod
    def from_dict(cls, d: Mapping, where: str = "kerb hint") -> KerbHint:
        d = _mapping(where, d)
        if "coords" not in d:
            raise SceneError(f"{where}: field 'coords': expected it, got nothing")
        return _build(cls, where, coords=d["coords"], width_m=d.get("width_m", 6.0), left=d.get("left"), right=d.get("right"))


@dataclass(frozen=True)
class NegativesHint:
    """The hard negatives a scene holds (objects like vehicles that are never labelled).

    scene_kind     : density table used (``residential_us``, ``rural``, ``osm``, ...)
    density_per_ha : ((kind, per hectare), ...)
    counts         : ((kind, number placed), ...)
    positions      : ((kind, x, y), ...) footprint centres, metres
    """

    scene_kind: str
    density_per_ha: tuple
    counts: tuple
    positions: tuple = ()
    labelled: bool = False

    def __post_init__(self) -> None:
        w = f"hard negatives of {self.scene_kind!r}"
        if not isinstance(self.scene_kind, str):
            _fail("hard negatives", "scene_kind", "a string", self.scene_kind)
        object.__setattr__(self, "density_per_ha", _weights(w, "density_per_ha", self.density_per_ha))
        object.__setattr__(self, "counts", _weights(w, "counts", self.counts))
        pos = []
        for p in self.positions:
            if len(p) != 3 or not isinstance(p[0], str):
                _fail(w, "positions", "[kind, x, y] entries", p)
            pos.append((p[0], p[1], p[2]))
        object.__setattr__(self, "positions", tuple(pos))
        if self.labelled is not False:
            _fail(w, "labelled", "false (hard negatives are never labelled)", self.labelled)

    @classmethod
    def from_dict(cls, d: Mapping, where: str = "hard negatives") -> NegativesHint:
        d = _mapping(where, d)
        try:
            return _build(cls, where, scene_kind=d["scene_kind"], density_per_ha=d["density_per_ha"], counts=d["counts"],
                       positions=tuple(d.get("positions") or ()), labelled=d.get("labelled", False))
        except KeyError as exc:
            raise SceneError(f"{where}: field {exc.args[0]!r}: expected it, got nothing") from None

    def to_dict(self) -> dict:
        """The metadata record written with every image of the scene."""
        return {"scene_kind": self.scene_kind, "density_per_ha": dict(self.density_per_ha),
                "counts": dict(self.counts), "labelled": False,
                "positions": [list(p) for p in self.positions]}


@dataclass(frozen=True, eq=False)
class SceneHints:
    """Every hint a scene carries for placement (see the module doc); empty by default."""

    roads: RoadHints | None = None
    driveways: tuple[DrivewayHint, ...] = ()
    lots: tuple[LotHint, ...] = ()
    spaces: tuple[np.ndarray, ...] = ()
    kerbs: tuple[KerbHint, ...] = ()
    negatives: NegativesHint | None = None

    def __post_init__(self) -> None:
        if self.roads is not None and not isinstance(self.roads, RoadHints):
            _fail("scene hints", "roads", "RoadHints or None", type(self.roads).__name__)
        for name, kind in (("driveways", DrivewayHint), ("lots", LotHint), ("kerbs", KerbHint)):
            items = tuple(getattr(self, name) or ())
            for i, h in enumerate(items):
                if not isinstance(h, kind):
                    _fail("scene hints", f"{name}[{i}]", kind.__name__, type(h).__name__)
            object.__setattr__(self, name, items)
        spaces = []
        for i, ring in enumerate(self.spaces or ()):
            r = np.asarray(ring, dtype=np.float64)
            if r.ndim != 2 or r.shape[1] != 2 or len(r) < 3:
                _fail("scene hints", f"spaces[{i}]", "a (k >= 3, 2) ring", f"shape {r.shape}")
            spaces.append(r)
        object.__setattr__(self, "spaces", tuple(spaces))
        if self.negatives is not None and not isinstance(self.negatives, NegativesHint):
            _fail("scene hints", "negatives", "NegativesHint or None", type(self.negatives).__name__)

    def replace(self, **kw) -> SceneHints:
        """A copy with the given fields replaced."""
        cur = {k: getattr(self, k) for k in ("roads", "driveways", "lots", "spaces", "kerbs", "negatives")}
        return SceneHints(**{**cur, **kw})

    def __bool__(self) -> bool:
        return bool((self.roads is not None and len(self.roads)) or self.driveways or self.lots
                    or self.spaces or self.kerbs or self.negatives is not None)


#: The hints of a scene without any.
NO_HINTS = SceneHints()
