"""Generator ``city``: a city of any size (``size_km``), a street grid of blocks and parks.

The world is ``size_km`` x ``size_km`` (metres: ``1000 * size_km``), centred on the origin.
Streets run north-south and east-west across the whole world at seeded spacings; every
``avenue_every``-th street is a wide avenue with two lanes per direction. The blocks
between them are built up (houses and offices in lots along the streets, sometimes a
parking lot on the street) or parks (trees, sometimes a pond).

Windows. Everything is decided from the world seed and an index, never from what else is
generated: street positions from the world stream, a block's buildings, trees, lot and pond
from ``SeedSequence([key, 1, i, j])``. So ``window_m: [x0, y0, x1, y1]`` in the spec
generates only the part of the world inside that rectangle (plus whole buildings and trees
that reach into it), and two windows agree on everything they share. This is what
:mod:`aerial_synth.scene.tiles` uses to build tiles of a world far larger than memory:
a 100 km world costs only the streets' positions until a window is generated.

Streets are clipped to the window (plus ``_PAD_M``) at multiples of ``_PHASE_M`` from the
world's edge, so lane-marking dashes and poles stand at the same places in every window.

Spec keys (all optional but ``size_km``; see docs/scale.md)::

    size_km: 2.0                   # world edge length, km
    block_m: [90, 140]             # block pitch range (street centre to street centre)
    street_width_m: 8.0            # two-way street, one lane per direction
    avenue_width_m: 14.0           # avenue carriageway width
    avenue_lanes: 2                # avenue lanes per direction (lane width = width / 2 / lanes)
    avenue_every: 3                # every k-th street is an avenue (0 = none)
    sidewalk_m: 2.5
    park_fraction: 0.2             # share of blocks that are parks
    parking_fraction: 0.25         # share of built blocks with a parking lot on a street
    pond_fraction: 0.3             # share of parks with a pond
    tree_density_per_ha: 25        # park trees per hectare
    building_height_m: [6, 30]
    window_m: [x0, y0, x1, y1]     # generate only this rectangle (metres, world frame)
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ...errors import SceneError
from ..build import merge_meshes
from ..model import SceneObject
from .builder import Builder
from .generators import Generator
from .roads import Road
from .roofs import ROOF_DETAIL_MAX_M, building_objects
from .trees import draw_species, tree_objects

__all__ = ["generate_city", "city_layout", "city_max_height_m", "with_size_m", "CityLayout",
           "CITY_DEFAULTS"]

#: Marking dash period (3 m dash + 6 m gap) times 4 = pole spacing: streets start at
#: multiples of this from the world's west/south edge in every window.
_PHASE_M = 36.0
#: Streets reach this far past the window (so junction clearing and markings match).
_PAD_M = 72.0

#: Heights (metres) of park trees, courtyard trees (crown tops: a crown ends at its tree's
#: height, procedural/trees.py) and of the poles along avenues.
_PARK_TREE_M = (7.0, 15.0)
_YARD_TREE_M = (6.0, 10.0)
_POLE_M = 9.0

CITY_DEFAULTS: dict = {
    "block_m": [90.0, 140.0],
    "street_width_m": 8.0,
    "avenue_width_m": 14.0,
    "avenue_lanes": 2,
    "avenue_every": 3,
    "sidewalk_m": 2.5,
    "park_fraction": 0.2,
    "parking_fraction": 0.25,
    "pond_fraction": 0.3,
    "tree_density_per_ha": 25.0,
    "building_height_m": [6.0, 30.0],
}



@dataclass(frozen=True)
class CityLayout:
    """The street grid of a whole city world (metres, world frame).

    xs, ys : street centre-line positions (north-south streets at x = xs, east-west at y = ys)
    wx, wy : their carriageway widths; avx, avy: avenue flags
    half_m : half the world's edge length
    """

    key: int
    half_m: float
    xs: np.ndarray
    ys: np.ndarray
    wx: np.ndarray
    wy: np.ndarray
    avx: np.ndarray
    avy: np.ndarray

    def block_edges(self, axis: int) -> np.ndarray:
        """Block boundaries along one axis: world edge, streets..., world edge."""
        s = self.xs if axis == 0 else self.ys
        return np.concatenate([[-self.half_m], s, [self.half_m]])


def _num(spec: Mapping, key: str):
    v = spec.get(key, CITY_DEFAULTS.get(key))
    return v


def _pair(spec: Mapping, key: str, lo: float = 0.0) -> tuple[float, float]:
    v = _num(spec, key)
    if not (isinstance(v, (list, tuple)) and len(v) == 2):
        raise SceneError(f"city: field {key!r} must be [min, max], got {v!r}")
    a, b = float(v[0]), float(v[1])
    if not (np.isfinite(a) and np.isfinite(b) and lo <= a <= b):
        raise SceneError(f"city: field {key!r} must be [min, max] with {lo} <= min <= max, got {v!r}")
    return a, b


def _positive(spec: Mapping, key: str, lo: float = 0.0, hi: float = float("inf")) -> float:
    v = _num(spec, key)
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise SceneError(f"city: field {key!r} must be a number, got {v!r}") from None
    if not (np.isfinite(f) and lo <= f <= hi):
        raise SceneError(f"city: field {key!r} must be in [{lo}, {hi}], got {v!r}")
    return f


def _lanes(spec: Mapping) -> int:
    """``avenue_lanes``: an integer number of lanes per direction, 1..6."""
    v = _num(spec, "avenue_lanes")
    if isinstance(v, bool) or not isinstance(v, (int, float)) or v != int(v) or not 1 <= v <= 6:
        raise SceneError(f"city: field 'avenue_lanes' must be an integer in [1, 6], got {v!r}")
    return int(v)


def with_size_m(spec: Mapping, where: str = "scene spec") -> Mapping:
    """``spec`` with ``size_m`` derived from ``size_km`` (the city generator's world size).

    Specs without ``size_km`` come back unchanged. A ``size_m`` that disagrees with
    ``size_km`` is refused, naming both."""
    if not isinstance(spec, Mapping) or "size_km" not in spec:
        return spec
    v = spec["size_km"]
    try:
        km = float(v)
    except (TypeError, ValueError):
        km = float("nan")
    if isinstance(v, bool) or not (np.isfinite(km) and 0.05 <= km <= 1000.0):
        raise SceneError(f"{where}: field 'size_km' must be a number of km in [0.05, 1000], got {v!r}")
    size = [1000.0 * km, 1000.0 * km]
    old = spec.get("size_m")
    if old is not None:
        try:
            same = len(old) == 2 and all(abs(float(a) - b) < 1e-6 for a, b in zip(old, size))
        except (TypeError, ValueError):
            same = False
        if not same:
            raise SceneError(f"{where}: field 'size_m' {old!r} disagrees with size_km {v!r}; give only size_km")
    return {**spec, "size_m": size}


def city_layout(spec: Mapping, key: int) -> CityLayout:
    """The street grid of the world of ``spec`` for world key ``key`` (cheap: O(streets))."""
    return _layout_cached(
        key,
        float(spec["size_m"][0]) if "size_m" in spec else 1000.0 * float(spec["size_km"]),
        _pair(spec, "block_m", 40.0),
        _positive(spec, "street_width_m", 4.0, 40.0),
        _positive(spec, "avenue_width_m", 4.0, 60.0),
        int(_positive(spec, "avenue_every", 0, 1e9)),
    )


@functools.lru_cache(maxsize=8)
def _layout_cached(key, size_m, block, street_w, avenue_w, avenue_every) -> CityLayout:
    half = size_m / 2.0
    rng = np.random.default_rng(np.random.SeedSequence([key, 0]))
    out = []
    for _axis in range(2):
        pos, p = [], -half
        while True:
            p += float(rng.uniform(block[0], block[1]))
            if p > half - block[0] / 2:
                break
            pos.append(p)
        pos = np.asarray(pos, float)
        av = (np.arange(len(pos)) % avenue_every == avenue_every // 2) if avenue_every else np.zeros(len(pos), bool)
        out.append((pos, np.where(av, avenue_w, street_w), av))
    (xs, wx, avx), (ys, wy, avy) = out
    return CityLayout(key, half, xs, ys, wx, wy, avx, avy)


def city_max_height_m(spec: Mapping) -> float:
    """How far the tallest structure of a city of ``spec`` can rise above its lowest surface
    (the ground and the ponds, z = 0; roads, markings and sidewalks lie 5-12 cm above it):
    the ``building_height_m`` upper bound plus the tallest roof detail
    (:data:`~.roofs.ROOF_DETAIL_MAX_M`, none with ``roofs: {enabled: false}`` or
    ``{details: false}``), or a park tree (15 m), or a pole (9 m), whichever is higher."""
    _, hmax = _pair(spec, "building_height_m", 2.0)
    roofs = spec.get("roofs") or {}
    details = roofs.get("enabled", True) and roofs.get("details", True)
    return float(max(hmax + (ROOF_DETAIL_MAX_M if details else 0.0), _PARK_TREE_M[1], _YARD_TREE_M[1],
                     _POLE_M))


def _span(lo: float, hi: float, w_lo: float, w_hi: float) -> tuple[float, float] | None:
    """Street span inside the window [w_lo, w_hi] (padded), snapped to the world phase."""
    a = max(lo, lo + np.floor((w_lo - _PAD_M - lo) / _PHASE_M) * _PHASE_M)
    b = min(hi, lo + np.ceil((w_hi + _PAD_M - lo) / _PHASE_M) * _PHASE_M)
    return (float(a), float(b)) if b > a else None


def generate_city(b: Builder, spec: Mapping) -> None:
    """Fill ``b`` with the part of the city world inside ``spec['window_m']`` (default:
    the whole world). Registered as generator ``city``."""
    import shapely
    from shapely.geometry import LineString

    if "size_km" not in spec:
        raise SceneError("city: field 'size_km' (world edge length in km) is required")
    key = int(b.rng.integers(2**62))  # the world key: the first draw of the spec's seed
    lay = city_layout(spec, key)
    b._city_key = key
    half = lay.half_m
    win = spec.get("window_m")
    if win is None:
        x0, y0, x1, y1 = -half, -half, half, half
    else:
        if not (isinstance(win, (list, tuple)) and len(win) == 4):
            raise SceneError(f"city: field 'window_m' must be [x0, y0, x1, y1] in metres, got {win!r}")
        x0, y0, x1, y1 = (float(v) for v in win)
        x0, y0, x1, y1 = max(x0, -half), max(y0, -half), min(x1, half), min(y1, half)
        if not (x1 > x0 and y1 > y0):
            raise SceneError(f"city: field 'window_m' {list(win)} does not overlap the world "
                             f"[{-half}, {-half}, {half}, {half}]")
    b.box = shapely.box(x0, y0, x1, y1)
    sidewalk = _positive(spec, "sidewalk_m", 0.0, 10.0)
    av_lanes = _lanes(spec)

    # ---- streets that reach into the padded window
    for axis, (pos, wid, av) in enumerate(((lay.xs, lay.wx, lay.avx), (lay.ys, lay.wy, lay.avy))):
        lo_w, hi_w = (x0, x1) if axis == 0 else (y0, y1)  # the street's own coordinate
        a_w, b_w = (y0, y1) if axis == 0 else (x0, x1)  # along the street
        for k, (p, w, is_av) in enumerate(zip(pos, wid, av)):
            if p + w / 2 + sidewalk < lo_w - _PAD_M or p - w / 2 - sidewalk > hi_w + _PAD_M:
                continue
            sp = _span(-half, half, a_w, b_w)
            if sp is None:
                continue
            pts = [(p, sp[0]), (p, sp[1])] if axis == 0 else [(sp[0], p), (sp[1], p)]
            b.roads.append(Road(
                name=f"{'ns' if axis == 0 else 'ew'}_{k}", line=LineString(pts), width_m=float(w),
                lanes=av_lanes if is_av else 1, sidewalk_m=sidewalk, centre="solid" if is_av else "dashed",
            ))
    if not b.roads:  # a window between streets: a short stub keeps generate() happy
        raise SceneError(f"city: window {[x0, y0, x1, y1]} holds no street; make it larger")

    # ---- blocks that touch the window (by their seeded content only)
    ex, ey = lay.block_edges(0), lay.block_edges(1)
    ix = np.flatnonzero((ex[1:] > x0 - 40.0) & (ex[:-1] < x1 + 40.0))
    iy = np.flatnonzero((ey[1:] > y0 - 40.0) & (ey[:-1] < y1 + 40.0))
    buildings: list[tuple] = []  # (polygon, height, unused draw)
    trees: list[np.ndarray] = []  # (k, 7) x, y, crown r, height, species, shape u, colour u
    park_f = _positive(spec, "park_fraction", 0.0, 1.0)
    lot_f = _positive(spec, "parking_fraction", 0.0, 1.0)
    pond_f = _positive(spec, "pond_fraction", 0.0, 1.0)
    density = _positive(spec, "tree_density_per_ha", 0.0, 400.0)
    hmin, hmax = _pair(spec, "building_height_m", 2.0)
    for i in ix:
        for j in iy:
            # block interior: between the sidewalks of its streets (world edge: no street)
            bx0 = ex[i] + (lay.wx[i - 1] / 2 + sidewalk if i > 0 else 0.0)
            bx1 = ex[i + 1] - (lay.wx[i] / 2 + sidewalk if i < len(lay.xs) else 0.0)
            by0 = ey[j] + (lay.wy[j - 1] / 2 + sidewalk if j > 0 else 0.0)
            by1 = ey[j + 1] - (lay.wy[j] / 2 + sidewalk if j < len(lay.ys) else 0.0)
            if bx1 - bx0 < 12.0 or by1 - by0 < 12.0:
                continue
            rng = np.random.default_rng(np.random.SeedSequence([key, 1, int(i), int(j)]))
            if rng.random() < park_f:
                _park(rng, (bx0, by0, bx1, by1), density, pond_f, b, trees)
            else:
                _built(rng, (bx0, by0, bx1, by1), (hmin, hmax), lot_f, b, buildings, trees,
                       edge_streets=(i > 0, j > 0, i < len(lay.xs), j < len(lay.ys)))
    b.freeze_areas()
    win_box = b.box
    b._city_buildings = [t for t in buildings if t[0].intersects(win_box)]
    tr = np.concatenate(trees) if trees else np.zeros((0, 7))
    if len(tr):
        keep = ((tr[:, 0] + tr[:, 2] > x0) & (tr[:, 0] - tr[:, 2] < x1)
                & (tr[:, 1] + tr[:, 2] > y0) & (tr[:, 1] - tr[:, 2] < y1))
        tr = tr[keep]
    b._city_trees = tr
    for r in b.roads:
        if r.lanes >= 2:
            b.add_poles_along(r, _PHASE_M, _POLE_M, r.sidewalk_m + 0.6)
    b.scene = functools.partial(_city_scene, b)  # buildings and trees with seeded colours


GENERATOR = Generator("city", generate_city)


def _park(rng, box, density, pond_f, b: Builder, trees: list) -> None:
    import shapely

    bx0, by0, bx1, by1 = box
    w, h = bx1 - bx0, by1 - by0
    pond = None
    if rng.random() < pond_f and min(w, h) > 50.0:
        cx, cy = bx0 + w * rng.uniform(0.35, 0.65), by0 + h * rng.uniform(0.35, 0.65)
        rx, ry = w * rng.uniform(0.15, 0.3), h * rng.uniform(0.15, 0.3)
        a = np.linspace(0, 2 * np.pi, 40, endpoint=False)
        k = rng.uniform(0.88, 1.12, 40)
        pond = shapely.Polygon(np.column_stack([cx + rx * k * np.cos(a), cy + ry * k * np.sin(a)]))
        b.water.append(pond)
    n = int(round(density * w * h / 1e4))
    if n <= 0:
        return
    xy = np.column_stack([rng.uniform(bx0 + 3, bx1 - 3, n), rng.uniform(by0 + 3, by1 - 3, n)])
    r = rng.uniform(2.5, 5.0, n)
    hgt = rng.uniform(*_PARK_TREE_M, n)
    sp, u = draw_species(rng, n, b.species_weights())
    col = rng.random(n)
    if pond is not None:
        ok = ~shapely.intersects(pond.buffer(1.0), shapely.points(xy))
        xy, r, hgt, sp, u, col = xy[ok], r[ok], hgt[ok], sp[ok], u[ok], col[ok]
    trees.append(np.column_stack([xy, r, hgt, sp, u, col]))


def _built(rng, box, heights, lot_f, b: Builder, buildings: list, trees: list, edge_streets) -> None:
    """Buildings in lots along the block's street sides; maybe a parking lot on a street."""
    import shapely

    bx0, by0, bx1, by1 = box
    lot = None
    if rng.random() < lot_f:
        # a parking lot on the block's west or south street, reaching over the sidewalk
        side = int(rng.integers(2))
        d = float(rng.uniform(25.0, 40.0))
        if side == 0 and edge_streets[0]:
            y_a = by0 + (by1 - by0) * float(rng.uniform(0.1, 0.4))
            lot = shapely.box(bx0 - 3.5, y_a, bx0 + d, min(by1 - 5.0, y_a + 35.0))
        elif side == 1 and edge_streets[1]:
            x_a = bx0 + (bx1 - bx0) * float(rng.uniform(0.1, 0.4))
            lot = shapely.box(x_a, by0 - 3.5, min(bx1 - 5.0, x_a + 35.0), by0 + d)
        if lot is not None and lot.area > 100.0:
            b.parking.append(lot)
        else:
            lot = None
    setback = float(rng.uniform(3.0, 6.0))
    depth = float(rng.uniform(12.0, 22.0))
    pitch = float(rng.uniform(16.0, 30.0))
    hmin, hmax = heights
    tall = float(rng.uniform(0.0, 1.0))
    inner = shapely.box(bx0 + setback, by0 + setback, bx1 - setback, by1 - setback)
    if inner.is_empty or inner.area < 100.0:
        return
    blocked = lot.buffer(3.0) if lot is not None else None
    rows = []
    ix0, iy0, ix1, iy1 = inner.bounds
    for x in np.arange(ix0, ix1 - 8.0, pitch):  # south and north rows
        rows.append((x, iy0, min(x + pitch - 3.0, ix1), iy0 + depth))
        rows.append((x, iy1 - depth, min(x + pitch - 3.0, ix1), iy1))
    for y in np.arange(iy0 + depth + 3.0, iy1 - depth - 8.0, pitch):  # west and east rows
        rows.append((ix0, y, ix0 + depth, min(y + pitch - 3.0, iy1 - depth - 3.0)))
        rows.append((ix1 - depth, y, ix1, min(y + pitch - 3.0, iy1 - depth - 3.0)))
    for r in rows:
        if r[2] - r[0] < 6.0 or r[3] - r[1] < 6.0 or rng.random() < 0.12:
            continue
        poly = shapely.box(*r)
        if blocked is not None and poly.intersects(blocked):
            continue
        h = float(hmin + (hmax - hmin) * rng.uniform(0.0, 1.0) ** (2.5 - 2.0 * tall))
        # the draw that picked a roof colour before roofs had seeds of their own (kept, so
        # the block's later draws and hence every layout stay as they were)
        buildings.append((poly, h, int(rng.integers(7))))
    # a few courtyard trees
    n = int(rng.integers(0, 6))
    if n and (iy1 - iy0) > 2 * depth + 12 and (ix1 - ix0) > 2 * depth + 12:
        xy = np.column_stack([rng.uniform(ix0 + depth + 4, ix1 - depth - 4, n),
                              rng.uniform(iy0 + depth + 4, iy1 - depth - 4, n)])
        r, hgt = rng.uniform(2.5, 4.0, n), rng.uniform(*_YARD_TREE_M, n)
        sp, u = draw_species(rng, n, b.species_weights())
        trees.append(np.column_stack([xy, r, hgt, sp, u, rng.random(n)]))


def _city_scene(b: Builder, source: str, meta: dict):
    """Builder.scene for the roads, ground, water and poles, then the city's buildings and
    trees with the colours their blocks drew (so every window colours them alike)."""
    poles, b.poles = b.poles, []  # poles too: 8-sided prisms without a trimesh call each
    b.buildings, b.trees = [], []
    scene = Builder.scene(b, source, meta)
    objs = scene.objects
    if poles:
        v, f = merge_meshes([_trunk(x, y, 0.12, h) for x, y, h in poles])
        objs.append(SceneObject("poles", "pole", v, f))
    bl = b._city_buildings  # roofs from each building's own seed: world key and position
    cents = [(p.centroid.x, p.centroid.y) for p, _, _ in bl]
    names = [f"building_{x:.2f}_{y:.2f}" for x, y in cents]
    seeds = [(b._city_key, int(round(x * 100)) + 2**40, int(round(y * 100)) + 2**40) for x, y in cents]
    objs.extend(building_objects([(p, h) for p, h, _ in bl], seeds, b.spec, names))
    tr = b._city_trees
    if len(tr):  # clumped crowns by species and colour (procedural/trees.py)
        objs.extend(tree_objects(tr, sub=int(b.spec.get("tree_subdivisions", 0))))
    scene.objects = [o for o in objs if o.n_triangles]
    return scene


def _trunk(x, y, radius, top):
    """An 8-sided vertical prism from the ground to ``top`` (no trimesh call per tree)."""
    a = np.arange(8) * (np.pi / 4)
    ring = np.column_stack([x + radius * np.cos(a), y + radius * np.sin(a)])
    v = np.concatenate([np.column_stack([ring, np.zeros(8)]), np.column_stack([ring, np.full(8, top)])])
    f = []
    for k in range(8):
        n = (k + 1) % 8
        f += [[k, n, 8 + n], [k, 8 + n, 8 + k]]
    for k in range(1, 7):
        f.append([8, 8 + k, 8 + k + 1])
    return v, np.asarray(f, np.int64)
