"""Validation of procedural scene specs: every field of every bundled generator.

:func:`check_spec` walks a parsed spec mapping field by field and returns a copy whose
numbers are plain floats/ints (same keys, same structure), so the generators read it with
``spec.get(key, default)`` exactly as before. Any bad field raises :class:`SceneError` with
one line naming the file and the field path, what was expected and what arrived::

    scenes/x.yaml: roads[2].width_m: expected a finite number > 0 and <= 200, got -7

Unknown keys are refused (listing the known ones), so a typo never passes silently. Bounds
keep generation finite: sizes up to 20 km, counts up to 20,000, spacings of at least 0.5 m.
``city`` (procedural/city.py) checks its own values; here it gets the common checks
(``generator``, ``name``, ``seed``, ``size_m``, ``markings``, ``tree_subdivisions``) and no
unknown keys.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping

from ... import validators as V
from ...errors import SceneError
from ..parking_layout import parse_layout
from .city import CITY_DEFAULTS
from .trees import species_weights

__all__ = ["check_spec", "check_seed", "MAX_SIZE_M", "MAX_COUNT"]

#: Largest scene edge of the bundled generators (metres).
MAX_SIZE_M = 20_000.0
#: Largest count of buildings or trees.
MAX_COUNT = 20_000
#: Smallest spacing of repeated things (dashes, poles, trees, houses), metres.
MIN_SPACING_M = 0.5

E = SceneError
Check = Callable[[str, Any], Any]


# -------------------------------------------------------------------- field checkers
def pos(hi: float = 1e4) -> Check:
    return lambda f, v: V.in_range(f, v, 0.0, hi, lo_open=True, error=E)


def nonneg(hi: float = 1e4) -> Check:
    return lambda f, v: V.in_range(f, v, 0.0, hi, error=E)


def num(lo: float = -1e5, hi: float = 1e5) -> Check:
    return lambda f, v: V.in_range(f, v, lo, hi, error=E)


def spacing(hi: float = 1e4) -> Check:
    return lambda f, v: V.in_range(f, v, MIN_SPACING_M, hi, error=E)


def integer(lo: int, hi: int) -> Check:
    return lambda f, v: V.integer(f, v, lo, hi, error=E)


def boolean(f: str, v: Any) -> bool:
    return V.boolean(f, v, error=E)


def text(f: str, v: Any) -> str:
    if not isinstance(v, str) or not v:
        raise SceneError(f"{f}: expected a non-empty text, got {V.show(v)}")
    return v


def choice(*options: str) -> Check:
    def check(f, v):
        if not isinstance(v, str) or v not in options:
            raise SceneError(f"{f}: expected one of {', '.join(options)}, got {V.show(v)}")
        return v

    return check


def prob(f: str, v: Any) -> float:
    return V.probability(f, v, error=E)


def pair(lo: float = -1e5, hi: float = 1e5, *, positive_only: bool = False) -> Check:
    """[a, b] of finite numbers (each > 0 with positive_only) within [lo, hi]."""

    def check(f, v):
        what = "> 0" if positive_only else f">= {lo:g}"
        expected = f"[a, b]: 2 finite numbers {what} and <= {hi:g}"
        if isinstance(v, (str, bytes, Mapping)) or not isinstance(v, (list, tuple)) or len(v) != 2:
            raise SceneError(f"{f}: expected {expected}, got {V.show(v)}")
        out = []
        for x in v:
            try:
                out.append(V.in_range(f, x, 0.0 if positive_only else lo, hi,
                                      lo_open=positive_only, error=E))
            except SceneError:
                raise SceneError(f"{f}: expected {expected}, got {V.show(v)}") from None
        return out

    return check


def span(lo: float = 0.0, hi: float = 1e4) -> Check:
    """[min, max] range of positive numbers with min <= max (a uniform draw's bounds)."""
    base = pair(lo, hi, positive_only=True)

    def check(f, v):
        a, b = base(f, v)
        if a > b:
            raise SceneError(f"{f}: expected [min, max] with min <= max, got {V.show(v)}")
        return [a, b]

    return check


#: Shortest road centre line accepted (metres): a shorter one has no surface to draw.
MIN_ROAD_LENGTH_M = 0.5


def points(f: str, v: Any) -> list:
    """A road's centre line: >= 2 [x, y] points, at least ``MIN_ROAD_LENGTH_M`` long."""
    if not isinstance(v, list) or len(v) < 2 or len(v) > 10_000:
        raise SceneError(f"{f}: expected a list of >= 2 [x, y] points (metres), got {V.show(v)}")
    out = [pair(-1e5, 1e5)(f"{f}[{i}]", p) for i, p in enumerate(v)]
    length = sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(out, out[1:]))
    if not length >= MIN_ROAD_LENGTH_M:
        raise SceneError(f"{f}: expected a centre line at least {MIN_ROAD_LENGTH_M:g} m long, "
                         f"got {length:.3g} m from {V.show(v)}")
    return out


def list_of(item: Check, max_len: int = 10_000) -> Check:
    def check(f, v):
        if not isinstance(v, list) or len(v) > max_len:
            raise SceneError(f"{f}: expected a list (at most {max_len} items), got {V.show(v)}")
        return [item(f"{f}[{i}]", x) for i, x in enumerate(v)]

    return check


def one_or_list(item: Check) -> Check:
    def check(f, v):
        if isinstance(v, list):
            if not v:
                raise SceneError(f"{f}: expected a number or a non-empty list, got []")
            return list_of(item, 100)(f, v)
        return item(f, v)

    return check


def nullable(item: Check) -> Check:
    return lambda f, v: None if v is None else item(f, v)


def section(fields: Mapping[str, Check], required: tuple[str, ...] = (),
            allow_none: bool = True) -> Check:
    """A mapping whose keys are all in ``fields``; ``null`` counts as an empty mapping."""

    def check(f, v):
        if v is None and allow_none:
            return None
        if not isinstance(v, Mapping):
            raise SceneError(f"{f}: expected a mapping of key: value, got {V.show(v)}")
        V.known_keys(f, v, tuple(fields), error=E)
        for k in required:
            if k not in v:
                raise SceneError(f"{f}: missing key {k!r}")
        return {k: fields[k](f"{f}.{k}", x) for k, x in v.items()}

    return check


# -------------------------------------------------------------------- shared sections
MARKINGS = section({
    "enabled": boolean,
    "marking_width_m": pos(2.0),
    "dash_m": spacing(1e3),
    "gap_m": spacing(1e3),
    "edge_inset_m": nonneg(50.0),
    "lane_width_m": pos(20.0),
    "centre_line_min_width_m": nonneg(1e3),
    "edge_line_min_width_m": nonneg(1e3),
    "junction_clear_m": nonneg(1e3),
})
BUILDINGS = section({
    "count": integer(0, MAX_COUNT),
    "width_m": span(0.0, 1e3),
    "depth_m": span(0.0, 1e3),
    "height_m": span(0.0, 1e3),
    "clearance_m": nonneg(1e3),
})
def species(f: str, v: Any) -> dict:
    """A tree species mix ``{broadleaf: 0.7, conifer: 0.3}`` (procedural/trees.py)."""
    species_weights(v, f)
    return {str(k): float(x) for k, x in v.items()}


TREE_SHAPE = {"crown_radius_m": span(0.0, 50.0), "height_m": span(0.0, 200.0), "species": species}
ROOFS = section({
    "enabled": boolean,
    "details": boolean,
    "materials": section({"roof_gravel": nonneg(1e6), "roof_tiles": nonneg(1e6),
                          "roof_metal": nonneg(1e6)}),
})
TRACKS = section({
    "enabled": boolean,
    "width_m": pos(3.0),
    "gauge_m": pos(5.0),
    "junction_clear_m": nonneg(1e3),
})
POLES = section({
    "min_road_width_m": nonneg(1e3),
    "spacing_m": spacing(),
    "height_m": pos(200.0),
    "offset_m": nonneg(1e3),
    "median_spacing_m": spacing(),
})
ROAD = section({
    "name": text,
    "points": points,
    "width_m": pos(200.0),
    "wiggle_m": nonneg(100.0),
    "sidewalk_m": nonneg(100.0),
    "lanes": integer(0, 16),
    "centre": choice("dashed", "solid", "none"),
    "start_on": text,
    "end_on": text,
    "dead_end": boolean,
    "oneway": boolean,
    "smooth": integer(0, 6),
}, required=("points",), allow_none=False)
LAKE = section({
    "center": pair(),
    "radii_m": pair(0.0, 1e4, positive_only=True),
    "road_clear_m": nonneg(1e3),
}, required=("center", "radii_m"), allow_none=False)
def _lot_layout(f: str, v: Any):
    """A lot's bay layout (scene/parking_layout.py validates it; the value is kept as given)."""
    parse_layout(v, f)
    return v


LOT = section({
    "center": pair(),
    "size_m": pair(0.0, 1e4, positive_only=True),
    "rotation_deg": num(-360.0, 360.0),
    "layout": _lot_layout,
    "entrance": boolean,
}, required=("center", "size_m"), allow_none=False)

_COMMON = ("name", "generator", "seed", "size_m", "markings", "tree_subdivisions", "tree_species",
           "roofs", "tracks")
#: generator -> top-level keys it cannot do without
REQUIRED: dict[str, tuple[str, ...]] = {"suburb": ("grid",), "highway": ("highway",)}

#: generator -> {top-level key: checker} (plus the common keys)
SCHEMAS: dict[str, dict[str, Check]] = {
    "city_park": {
        "roads": list_of(ROAD, 1000),
        "lakes": nullable(list_of(LAKE, 100)),
        "buildings": BUILDINGS,
        "trees": section({
            "rows": section({"roads": list_of(text, 1000), "spacing_m": spacing(),
                             "offset_m": nonneg(1e3), **TREE_SHAPE}),
            "park": section({"count": integer(0, MAX_COUNT), **TREE_SHAPE}),
        }),
        "poles": POLES,
    },
    "suburb": {
        "grid": section({
            "blocks_x": integer(1, 50),
            "blocks_y": integer(1, 50),
            "street_width_m": pos(200.0),
            "main_width_m": pos(200.0),
            "main_streets_x": list_of(integer(0, 49), 50),
            "sidewalk_m": nonneg(100.0),
            "jitter_m": nonneg(1e3),
            "cul_de_sac": section({"street": integer(0, 48), "from_ew": integer(0, 48),
                                   "length_m": pos(1e4)}),
        }, required=("blocks_x", "blocks_y"), allow_none=False),
        "parking_lots": nullable(list_of(LOT, 1000)),
        "houses": section({
            "spacing_m": spacing(),
            "setback_m": nonneg(1e3),
            "width_m": span(0.0, 1e3),
            "depth_m": span(0.0, 1e3),
            "height_m": span(0.0, 1e3),
            "driveway_width_m": pos(100.0),
            "driveway_prob": prob,
        }),
        "trees": section({
            "street": section({"spacing_m": spacing(), "offset_m": nonneg(1e3), **TREE_SHAPE}),
            "yard": section({"count": integer(0, MAX_COUNT), **TREE_SHAPE}),
        }),
        "poles": POLES,
    },
    "depot": {
        "road_width_m": pos(200.0),
        "yards": nullable(list_of(LOT, 100)),
        "garage": section({"center": pair(), "size_m": pair(0.0, 1e4, positive_only=True),
                           "height_m": pos(200.0)}, required=("center", "size_m")),
        "trees": section({"count": integer(0, MAX_COUNT), "species": species}),
    },
    "highway": {
        "highway": section({
            "lanes": integer(1, 16),
            "lane_width_m": pos(20.0),
            "shoulder_right_m": nonneg(50.0),
            "shoulder_left_m": nonneg(50.0),
            "median_m": pos(1e3),
            "curve_amplitude_m": nonneg(1e4),
            "junction_x_m": one_or_list(num()),
            "crossing_width_m": pos(200.0),
            "crossing_straight_m": nonneg(1e4),
            "crossing_bend_m": nonneg(1e4),
            "median_opening_m": nonneg(1e3),
            "local_roads": section({"north_m": nullable(pos(1e5)), "south_m": nullable(pos(1e5)),
                                    "width_m": pos(200.0), "wiggle_m": nonneg(1e3),
                                    "clear_m": nonneg(1e4)}),
        }, allow_none=False),
        "trees": section({"count": integer(0, MAX_COUNT), **TREE_SHAPE}),
        "buildings": BUILDINGS,
        "poles": POLES,
    },
}


def check_seed(field: str, value: Any) -> int:
    """A seed: an integer >= 0 (numpy's SeedSequence refuses negative ones)."""
    return V.integer(field, value, 0, None, error=E)


def check_spec(spec: Any, where: str, generators: Mapping, seed: Any = None) -> tuple[dict, int]:
    """Validate ``spec`` (a parsed YAML mapping) for its generator.

    ``generators`` : the known generator names (the package's ``GENERATORS`` registry,
    passed in so this module does not import its package back).
    Returns (normalised spec, seed); ``seed`` (when not None) overrides the spec's seed and
    is validated the same way. Raises SceneError: ``<where>: <field>: expected ..., got ...``.
    """
    try:
        return _check(spec, seed, generators)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None


def _check(spec: Any, seed: Any, generators) -> tuple[dict, int]:
    if not isinstance(spec, Mapping):
        raise SceneError(f"expected a mapping of key: value, got {V.show(spec)}")
    kind = spec.get("generator")
    if not isinstance(kind, str) or kind not in generators:
        raise SceneError(f"generator: expected one of {', '.join(generators)}, got {V.show(kind)}")
    out = dict(spec)
    if "name" in spec:
        out["name"] = text("name", spec["name"])
    s = check_seed("seed", spec.get("seed", 0))
    if seed is not None:
        s = check_seed("seed", seed)
    size_hi = MAX_SIZE_M if kind in SCHEMAS else 1e7
    if "size_m" not in spec:
        raise SceneError("size_m: missing; expected [width, height] in metres")
    out["size_m"] = list(pair(0.0, size_hi, positive_only=True)("size_m", spec["size_m"]))
    if "markings" in spec:
        out["markings"] = MARKINGS("markings", spec["markings"])
    if "tree_subdivisions" in spec:
        out["tree_subdivisions"] = integer(0, 4)("tree_subdivisions", spec["tree_subdivisions"])
    if "tree_species" in spec:
        out["tree_species"] = species("tree_species", spec["tree_species"])
    if "roofs" in spec:
        out["roofs"] = ROOFS("roofs", spec["roofs"])
    if "tracks" in spec:
        out["tracks"] = TRACKS("tracks", spec["tracks"])
    if kind == "city":  # procedural/city.py checks its values; here: no unknown keys

        V.known_keys("top level", spec, _COMMON + ("size_km", "window_m") + tuple(CITY_DEFAULTS),
                     error=E)
    schema = SCHEMAS.get(kind)
    if schema is None:  # another generator checks its own keys
        return out, s
    allowed = _COMMON + tuple(schema)
    V.known_keys("top level", spec, allowed, error=E)
    for key in REQUIRED.get(kind, ()):
        if key not in spec:
            raise SceneError(f"{key}: missing; the {kind} generator needs it (see docs/scenes.md)")
    for key, check in schema.items():
        if key in spec:
            out[key] = check(key, spec[key])
    _cross_checks(kind, out)
    return out, s


def _cross_checks(kind: str, spec: dict) -> None:
    """Relations between fields that single-field checks cannot see."""
    if kind == "city_park":
        names: list[str] = []
        for i, r in enumerate(spec.get("roads") or []):
            for key in ("start_on", "end_on"):
                other = r.get(key)
                if other is not None and other not in names:
                    raise SceneError(
                        f"roads[{i}].{key}: expected the name of an earlier road "
                        f"({', '.join(names) or 'none yet'}), got {V.show(other)}"
                    )
            names.append(str(r.get("name", f"r{i}")))
    if kind == "suburb":
        g = spec["grid"]
        nx, ny = g["blocks_x"], g["blocks_y"]
        for i, k in enumerate(g.get("main_streets_x") or []):
            if k >= nx - 1:
                raise SceneError(
                    f"grid.main_streets_x[{i}]: expected a street index below {nx - 1} "
                    f"(blocks_x - 1), got {k}"
                )
        cds = g.get("cul_de_sac")
        if cds:
            if nx < 2 or ny < 2:
                raise SceneError("grid.cul_de_sac: needs blocks_x >= 2 and blocks_y >= 2")
            if "street" not in cds:
                raise SceneError("grid.cul_de_sac: missing key 'street'")
            if cds["street"] >= nx - 1:
                raise SceneError(
                    f"grid.cul_de_sac.street: expected an index below {nx - 1}, got {cds['street']}"
                )
            if cds.get("from_ew", 0) >= ny - 1:
                raise SceneError(
                    f"grid.cul_de_sac.from_ew: expected an index below {ny - 1}, "
                    f"got {cds.get('from_ew', 0)}"
                )
