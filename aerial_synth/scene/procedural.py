"""Seeded procedural scenes: roads, markings, sidewalks, buildings, trees, poles, water.

A scene spec is a YAML mapping (see ``scenes/*.yaml`` and ``docs/scenes.md``) holding the
seed, the size and every generator parameter. :func:`generate` turns a spec mapping into a
:class:`~aerial_synth.scene.model.Scene`; the same spec and seed always give the same
vertices (checked with :meth:`Scene.vertex_hash`).

World frame: metres, x east, y north, z up; the scene is centred on the origin.
Heights: ground 0.0, road and parking 0.05, lane markings 0.06, sidewalks raised 0.12.
Ground has holes where roads, parking and water are, so no two surfaces share a height
over the same point.

The generator also fills ``Scene.truth`` (road polygons and centre lines) for tests and the
validator; placement never reads it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..errors import SceneError
from .build import cylinder, ellipsoid, merge_meshes, polygon_object, prism
from .model import LabelConfig, RoadTruth, Scene, SceneObject, SceneTruth

__all__ = ["generate", "GENERATORS", "Z_GROUND", "Z_ROAD", "Z_MARKING", "Z_SIDEWALK"]

Z_GROUND = 0.0
Z_ROAD = 0.05
Z_MARKING = 0.06
Z_SIDEWALK = 0.12

_ROOF_COLORS = (
    (0.55, 0.30, 0.24),
    (0.42, 0.22, 0.18),
    (0.35, 0.35, 0.37),
    (0.62, 0.58, 0.52),
    (0.25, 0.27, 0.30),
    (0.70, 0.45, 0.32),
    (0.48, 0.50, 0.46),
)
_FOLIAGE_COLORS = (
    (0.16, 0.32, 0.12),
    (0.20, 0.36, 0.14),
    (0.13, 0.27, 0.11),
    (0.24, 0.34, 0.16),
)


# --------------------------------------------------------------------------- road model
@dataclass(frozen=True)
class _Road:
    """One generated road.

    line : shapely LineString centre line, metres, world xy
    width_m : carriageway width (edge to edge)
    oneway : traffic follows the line direction (one carriageway of a dual carriageway)
    lanes : lanes in the line direction (oneway) or per direction (two-way); 0 = unmarked
    sidewalk_m : sidewalk width on both sides (0 = none)
    dead_end : end with a turning circle
    centre : centre-line style for two-way roads: "dashed", "solid" or "none"
    """

    name: str
    line: Any
    width_m: float
    oneway: bool = False
    lanes: int = 1
    sidewalk_m: float = 0.0
    dead_end: bool = False
    centre: str = "dashed"
    shoulder_left_m: float = 0.0


def _chaikin(pts: np.ndarray, iterations: int = 3) -> np.ndarray:
    """Corner-cutting smoothing of an open polyline (end points kept). pts: (n, 2)."""
    for _ in range(iterations):
        if len(pts) < 3:
            return pts
        a, b = pts[:-1], pts[1:]
        q = 0.75 * a + 0.25 * b
        r = 0.25 * a + 0.75 * b
        mid = np.empty((2 * (len(pts) - 1), 2))
        mid[0::2] = q
        mid[1::2] = r
        pts = np.vstack([pts[:1], mid[1:-1], pts[-1:]])
    return pts


def _wiggle(pts: np.ndarray, amp_m: float, rng: np.random.Generator) -> np.ndarray:
    """Move interior points sideways by up to amp_m (seeded), keep the ends."""
    pts = np.array(pts, float)
    if amp_m <= 0 or len(pts) < 3:
        return pts
    d = np.gradient(pts, axis=0)
    n = np.column_stack([-d[:, 1], d[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    off = rng.uniform(-amp_m, amp_m, len(pts))
    off[0] = off[-1] = 0.0
    return pts + n * off[:, None]


def _road_polygon(r: _Road):
    import shapely

    poly = r.line.buffer(r.width_m / 2, cap_style="flat", join_style="round", quad_segs=8)
    if r.dead_end:
        end = shapely.Point(r.line.coords[-1])
        poly = poly.union(end.buffer(max(r.width_m, 7.0), quad_segs=12))
    return poly


def _dashes(line, dash_m: float, gap_m: float, width_m: float):
    """Union of dash rectangles along ``line`` (shapely), flat caps."""
    import shapely
    from shapely.ops import substring

    L = line.length
    pieces = []
    s = gap_m / 2
    while s < L:
        seg = substring(line, s, min(s + dash_m, L))
        if seg.length > 0.2:
            pieces.append(seg)
        s += dash_m + gap_m
    if not pieces:
        return shapely.Polygon()
    return shapely.union_all(shapely.buffer(pieces, width_m / 2, cap_style="flat"))


def _solid(line, width_m: float):
    return line.buffer(width_m / 2, cap_style="flat")


def _offset(line, d: float):
    """Offset a centre line by d metres (positive = left of the line direction)."""
    out = line.offset_curve(d, quad_segs=8, join_style="round")
    return out


def _markings(r: _Road, others_area, cfg: Mapping):
    """Lane-marking polygon of one road, clipped to its own surface and kept out of
    junctions (``others_area`` = the other roads' surfaces)."""
    import shapely

    mw = float(cfg.get("marking_width_m", 0.15))
    dash, gap = float(cfg.get("dash_m", 3.0)), float(cfg.get("gap_m", 6.0))
    edge_in = float(cfg.get("edge_inset_m", 0.3))
    if r.lanes <= 0:
        return shapely.Polygon()
    parts = []
    w = r.width_m
    if r.oneway:
        left = w / 2 - r.shoulder_left_m
        lane_w = float(cfg.get("lane_width_m", 3.5))
        parts.append(_solid(_offset(r.line, w / 2 - edge_in), mw))  # left edge
        parts.append(_solid(_offset(r.line, -(w / 2 - edge_in)), mw))  # right edge
        for k in range(1, r.lanes):
            parts.append(_dashes(_offset(r.line, left - k * lane_w), dash, gap, mw))
    else:
        if w >= float(cfg.get("centre_line_min_width_m", 6.0)):
            if r.centre == "solid":
                parts.append(_solid(r.line, mw))
            elif r.centre == "dashed":
                parts.append(_dashes(r.line, dash, gap, mw))
        if w >= float(cfg.get("edge_line_min_width_m", 7.0)):
            parts.append(_solid(_offset(r.line, w / 2 - edge_in), mw))
            parts.append(_solid(_offset(r.line, -(w / 2 - edge_in)), mw))
    m = shapely.union_all([p for p in parts if not p.is_empty])
    own = r.line.buffer(w / 2 - 0.05, cap_style="flat")
    m = m.intersection(own)
    if others_area is not None and not others_area.is_empty:
        m = m.difference(others_area.buffer(float(cfg.get("junction_clear_m", 1.5))))
    return m


def _polygonal(g):
    """The polygon parts of a shapely geometry (drops stray lines/points of a clip)."""
    import shapely

    parts = [p for p in shapely.get_parts(g) if p.geom_type in ("Polygon", "MultiPolygon")]
    return shapely.union_all(parts) if parts else shapely.Polygon()


# --------------------------------------------------------------------------- assembly
class _Builder:
    """Collects polygons and meshes, then emits labelled objects and truth."""

    def __init__(self, name: str, spec: Mapping, rng: np.random.Generator):
        import shapely

        self.name = name
        self.spec = spec
        self.rng = rng
        w, h = (float(v) for v in spec["size_m"])
        self.box = shapely.box(-w / 2, -h / 2, w / 2, h / 2)
        self.roads: list[_Road] = []
        self.parking = []  # shapely polygons
        self.water = []
        self.buildings: list[tuple[Any, float]] = []  # (polygon, height)
        self.trees: list[tuple[float, float, float, float, float]] = []  # x, y, r, h, trunk_h
        self.poles: list[tuple[float, float, float]] = []  # x, y, height
        self.pads = []  # extra road polygons not tied to a centre line (median openings)

    # ---- areas
    def road_area(self):
        import shapely

        if not hasattr(self, "_road_area"):
            polys = [_road_polygon(r) for r in self.roads]
            self._road_polys = [p.intersection(self.box) for p in polys]
            self._road_area = shapely.union_all(self._road_polys + list(self.pads)).intersection(self.box)
        return self._road_area

    def water_area(self):
        import shapely

        return shapely.union_all(self.water) if self.water else shapely.Polygon()

    def parking_area(self):
        import shapely

        if not self.parking:
            return shapely.Polygon()
        return (
            shapely.union_all(self.parking)
            .difference(self.road_area())
            .difference(self.water_area())
            .intersection(self.box)
        )

    def sidewalk_area(self):
        import shapely

        bands = [
            r.line.buffer(r.width_m / 2 + r.sidewalk_m, cap_style="flat")
            for r in self.roads
            if r.sidewalk_m > 0
        ]
        if not bands:
            return shapely.Polygon()
        sw = shapely.union_all(bands).intersection(self.box)
        return (
            sw.difference(self.road_area().buffer(1e-3))
            .difference(self.parking_area().buffer(1e-3))
            .difference(self.water_area())
        )

    def blocked(self):
        """Area where buildings and trunks may not stand (roads, parking, sidewalk, water)."""
        import shapely

        return shapely.union_all(
            [self.road_area(), self.parking_area(), self.sidewalk_area(), self.water_area()]
        )

    # ---- placement helpers
    def try_building(self, poly, height: float, clearance: float = 2.0) -> bool:

        if not self.box.buffer(-1.0).contains(poly):
            return False
        if poly.buffer(clearance).intersects(self._blocked):
            return False
        if self.buildings:
            tree = self._building_tree()
            if len(tree.query(poly.buffer(clearance), predicate="intersects")):
                return False
        self.buildings.append((poly, float(height)))
        self._btree = None
        return True

    def _building_tree(self):
        import shapely

        if getattr(self, "_btree", None) is None:
            self._btree = shapely.STRtree([b[0] for b in self.buildings])
        return self._btree

    def trunk_ok(self, xy: np.ndarray, clearance: float) -> np.ndarray:
        """(n,) bool: trunk positions xy (n, 2) away from roads, water, buildings, trees."""
        import shapely

        pts = shapely.points(xy)
        ok = ~shapely.intersects(self._blocked_buf(clearance), pts)
        ok &= shapely.contains(self.box.buffer(-1.0), pts)
        if self.buildings:
            bu = shapely.union_all([b[0] for b in self.buildings]).buffer(1.0)
            ok &= ~shapely.intersects(bu, pts)
        return ok

    def _blocked_buf(self, clearance):
        key = round(clearance, 3)
        cache = self.__dict__.setdefault("_bb_cache", {})
        if key not in cache:
            import shapely

            g = self._blocked.buffer(clearance)
            shapely.prepare(g)
            cache[key] = g
        return cache[key]

    def add_tree_row(self, line, spacing_m, crown_r, height, trunk_frac=0.4, jitter_m=0.5):
        """Trees along a line (shapely); crowns may overhang, trunks must be clear."""
        import shapely

        L = line.length
        if L < spacing_m:
            return
        s = np.arange(spacing_m / 2, L, spacing_m)
        pts = shapely.get_coordinates(shapely.line_interpolate_point(line, s))
        pts = pts + self.rng.uniform(-jitter_m, jitter_m, pts.shape)
        self._add_trees(pts, crown_r, height, trunk_frac)

    def add_tree_cluster(self, n, region, crown_r, height, trunk_frac=0.4):
        """n random trees in a shapely region."""
        import shapely

        minx, miny, maxx, maxy = region.bounds
        pts = np.column_stack(
            [self.rng.uniform(minx, maxx, 4 * n), self.rng.uniform(miny, maxy, 4 * n)]
        )
        inside = shapely.contains(region, shapely.points(pts))
        self._add_trees(pts[inside][:n], crown_r, height, trunk_frac)

    def _add_trees(self, pts, crown_r, height, trunk_frac):
        if len(pts) == 0:
            return
        n = len(pts)
        r = self.rng.uniform(crown_r[0], crown_r[1], n)
        h = self.rng.uniform(height[0], height[1], n)
        ok = self.trunk_ok(pts, 0.6)
        for (x, y), rr, hh, good in zip(pts, r, h, ok):
            if good:
                self.trees.append((float(x), float(y), float(rr), float(hh), float(hh * trunk_frac)))

    def add_poles_along(self, r: _Road, spacing_m: float, height_m: float, side_offset_m: float):
        import shapely

        for sign in (1.0, -1.0):
            off = _offset(r.line, sign * (r.width_m / 2 + side_offset_m))
            if off.is_empty:
                continue
            s = np.arange(spacing_m / 2, off.length, spacing_m)
            pts = shapely.get_coordinates(shapely.line_interpolate_point(off, s))
            if len(pts) == 0:
                continue
            ra = self._road_prepared()
            ok = ~shapely.intersects(ra, shapely.points(pts))
            ok &= ~shapely.intersects(self.water_area().buffer(0.5), shapely.points(pts))
            ok &= shapely.contains(self.box.buffer(-1.0), shapely.points(pts))
            for (x, y), good in zip(pts, ok):
                if good:
                    self.poles.append((float(x), float(y), float(height_m)))

    def _road_prepared(self):
        import shapely

        if not hasattr(self, "_ra_prep"):
            g = self.road_area().union(self.parking_area()).buffer(0.4)
            shapely.prepare(g)
            self._ra_prep = g
        return self._ra_prep

    def freeze_areas(self):
        """Call once roads, parking and water are final (before buildings/trees/poles)."""
        import shapely

        self._blocked = self.blocked()
        shapely.prepare(self._blocked)

    # ---- output
    def scene(self, source: str, meta: dict) -> Scene:
        import shapely

        objs: list[SceneObject] = []
        road_area = self.road_area()
        parking = self.parking_area()
        water = self.water_area().intersection(self.box)
        sidewalk = self.sidewalk_area()

        ground = _polygonal(self.box.difference(road_area).difference(parking).difference(water))
        objs.append(polygon_object("ground", "ground", ground, Z_GROUND))
        for i, part in enumerate(shapely.get_parts(road_area)):
            objs.append(polygon_object(f"road_{i:03d}", "road", part, Z_ROAD))
        if not parking.is_empty:
            objs.append(polygon_object("parking", "parking", parking, Z_ROAD))
        if not water.is_empty:
            objs.append(polygon_object("water_lake", "water", water, Z_GROUND))
        if not sidewalk.is_empty:
            v, f = prism(sidewalk, Z_GROUND, Z_SIDEWALK)
            objs.append(SceneObject("sidewalk", "sidewalk", v, f))
        mcfg = self.spec.get("markings", {}) or {}
        if mcfg.get("enabled", True):
            for i, r in enumerate(self.roads):
                others = [p for j, p in enumerate(self._road_polys) if j != i] + list(self.pads)
                others_area = shapely.union_all(others) if others else None
                m = _polygonal(_markings(r, others_area, mcfg).intersection(road_area))
                if not m.is_empty:
                    objs.append(polygon_object(f"lane_marking_{r.name}", "lane_marking", m, Z_MARKING))
        for i, (poly, hgt) in enumerate(self.buildings):
            v, f = prism(poly, Z_GROUND, hgt)
            col = _ROOF_COLORS[int(self.rng.integers(len(_ROOF_COLORS)))]
            objs.append(SceneObject(f"building_{i:03d}", "building", v, f, color=col))
        # trees grouped by foliage colour (few objects, many triangles)
        crown_sub = int(self.spec.get("tree_subdivisions", 1))
        groups: dict[int, list] = {}
        trunks = []
        for x, y, r, h, th in self.trees:
            k = int(self.rng.integers(len(_FOLIAGE_COLORS)))
            rz = max((h - th) / 2, 0.6 * r)
            groups.setdefault(k, []).append(ellipsoid((x, y, h - rz), (r, r, rz), crown_sub))
            trunks.append(cylinder((x, y), max(0.12, 0.06 * r), Z_GROUND, h - rz + 0.3 * rz, 8))
        for k in sorted(groups):
            v, f = merge_meshes(groups[k])
            objs.append(SceneObject(f"tree_crowns_{k}", "tree", v, f, color=_FOLIAGE_COLORS[k]))
        if trunks:
            v, f = merge_meshes(trunks)
            objs.append(SceneObject("trunks", "trunk", v, f))
        if self.poles:
            v, f = merge_meshes([cylinder((x, y), 0.12, Z_GROUND, h, 8) for x, y, h in self.poles])
            objs.append(SceneObject("poles", "pole", v, f))
        objs = [o for o in objs if o.n_triangles]

        truth = SceneTruth(
            road_area=road_area,
            roads=tuple(
                RoadTruth(r.line, r.width_m, r.oneway, r.name) for r in self.roads
            ),
            parking_area=None if parking.is_empty else parking,
        )
        return Scene(
            name=self.name,
            objects=objs,
            source=source,
            truth=truth,
            label_config=LabelConfig(),
            meta=meta,
        )


# --------------------------------------------------------------------------- generators
def _spec_roads(b: _Builder, items, default_width):
    """Roads from explicit spec entries (points in metres; wiggle; T-junction snapping)."""
    import shapely
    from shapely.geometry import LineString

    by_name: dict[str, Any] = {}
    for k, it in enumerate(items):
        name = str(it.get("name", f"r{k}"))
        pts = np.asarray(it["points"], float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise SceneError(f"road {name!r}: points must be a list of >= 2 [x, y] pairs")
        pts = _wiggle(pts, float(it.get("wiggle_m", 0.0)), b.rng)
        for end, key in ((0, "start_on"), (-1, "end_on")):
            other = it.get(key)
            if other is not None:
                if other not in by_name:
                    raise SceneError(f"road {name!r}: {key} names unknown earlier road {other!r}")
                ol = by_name[other]
                p = ol.interpolate(ol.project(shapely.Point(pts[end])))
                pts[end] = (p.x, p.y)
        pts = _chaikin(pts, int(it.get("smooth", 3)))
        line = LineString(pts)
        by_name[name] = line
        b.roads.append(
            _Road(
                name=name,
                line=line,
                width_m=float(it.get("width_m", default_width)),
                oneway=bool(it.get("oneway", False)),
                lanes=int(it.get("lanes", 1)),
                sidewalk_m=float(it.get("sidewalk_m", 0.0)),
                dead_end=bool(it.get("dead_end", False)),
                centre=str(it.get("centre", "dashed")),
            )
        )


def _lake(b: _Builder, spec: Mapping):
    import shapely

    c = np.asarray(spec["center"], float)
    rx, ry = (float(v) for v in spec["radii_m"])
    n = 48
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    k = b.rng.uniform(0.85, 1.15, n)
    k = np.convolve(np.r_[k[-2:], k, k[:2]], np.ones(5) / 5, mode="valid")
    poly = shapely.Polygon(np.column_stack([c[0] + rx * k * np.cos(a), c[1] + ry * k * np.sin(a)]))
    poly = poly.buffer(0).difference(b.road_area().buffer(float(spec.get("road_clear_m", 8.0))))
    if not poly.is_empty:
        b.water.append(poly)


def _random_buildings(b: _Builder, spec: Mapping, region=None):
    import shapely
    from shapely import affinity

    n = int(spec.get("count", 0))
    if n <= 0:
        return
    region = region if region is not None else b.box
    minx, miny, maxx, maxy = region.bounds
    wr, dr, hr = spec.get("width_m", [10, 25]), spec.get("depth_m", [8, 18]), spec.get(
        "height_m", [4, 15]
    )
    clearance = float(spec.get("clearance_m", 4.0))
    placed, tries = 0, 0
    while placed < n and tries < 60 * n:
        tries += 1
        x, y = b.rng.uniform(minx, maxx), b.rng.uniform(miny, maxy)
        w, d, h = b.rng.uniform(*wr), b.rng.uniform(*dr), b.rng.uniform(*hr)
        ang = b.rng.uniform(0, 180)
        poly = affinity.rotate(shapely.box(x - w / 2, y - d / 2, x + w / 2, y + d / 2), ang)
        if not region.contains(poly):
            continue
        if b.try_building(poly, h, clearance):
            placed += 1


def _gen_city_park(b: _Builder, spec: Mapping):
    _spec_roads(b, spec.get("roads", []), 8.0)
    for lk in spec.get("lakes", []) or []:
        _lake(b, lk)
    b.freeze_areas()
    _random_buildings(b, spec.get("buildings", {}) or {})
    t = spec.get("trees", {}) or {}
    row = t.get("rows", {}) or {}
    for r in b.roads:
        if r.name in set(row.get("roads", [])):
            for sign in (1.0, -1.0):
                off = _offset(r.line, sign * (r.width_m / 2 + r.sidewalk_m + float(row.get("offset_m", 2.5))))
                b.add_tree_row(
                    off, float(row.get("spacing_m", 12.0)), row.get("crown_radius_m", [3.5, 5.0]),
                    row.get("height_m", [9, 14]),
                )
    cl = t.get("park", {}) or {}
    if int(cl.get("count", 0)) > 0:
        free = b.box.difference(b._blocked.buffer(3.0))
        b.add_tree_cluster(int(cl["count"]), free, cl.get("crown_radius_m", [2.5, 5.5]),
                           cl.get("height_m", [6, 16]))
    p = spec.get("poles", {}) or {}
    for r in b.roads:
        if r.width_m >= float(p.get("min_road_width_m", 8.0)):
            b.add_poles_along(r, float(p.get("spacing_m", 35.0)), float(p.get("height_m", 8.0)),
                              r.sidewalk_m + float(p.get("offset_m", 0.6)))


def _gen_suburb(b: _Builder, spec: Mapping):
    import shapely
    from shapely import affinity
    from shapely.geometry import LineString

    g = spec["grid"]
    W, H = (float(v) for v in spec["size_m"])
    nx, ny = int(g["blocks_x"]), int(g["blocks_y"])
    bw, bh = W / nx, H / ny
    sw = float(g.get("street_width_m", 7.5))
    side = float(g.get("sidewalk_m", 2.0))
    jit = float(g.get("jitter_m", 4.0))
    xs = -W / 2 + bw * np.arange(1, nx)
    ys = -H / 2 + bh * np.arange(1, ny)
    xs = xs + b.rng.uniform(-jit, jit, len(xs))
    ys = ys + b.rng.uniform(-jit, jit, len(ys))
    main = set(int(i) for i in g.get("main_streets_x", []))
    for i, x in enumerate(xs):
        w = float(g.get("main_width_m", 10.0)) if i in main else sw
        b.roads.append(_Road(f"ns_{i}", LineString([(x, -H / 2), (x, H / 2)]), w, sidewalk_m=side))
    for j, y in enumerate(ys):
        b.roads.append(_Road(f"ew_{j}", LineString([(-W / 2, y), (W / 2, y)]), sw, sidewalk_m=side))
    # a cul-de-sac running north into the block east of street ``street`` (from the middle of
    # that block's south side, a T-junction on the east-west street ``from_ew``)
    cds = g.get("cul_de_sac")
    if cds:
        i = int(cds["street"])
        x0 = float(xs[i])
        x1 = float(xs[i + 1]) if i + 1 < len(xs) else W / 2
        xm = 0.5 * (x0 + x1)
        y0 = float(ys[int(cds.get("from_ew", 0))])
        L = float(cds.get("length_m", 50))
        b.roads.append(_Road("cul_de_sac", LineString([(xm, y0), (xm + 0.001, y0 + L)]), 6.0,
                             dead_end=True, centre="none", sidewalk_m=0.0))
    ra = b.road_area()
    # parking lots
    lots = spec.get("parking_lots", []) or []
    for lot in lots:
        cx, cy = (float(v) for v in lot["center"])
        lw, lh = (float(v) for v in lot["size_m"])
        b.parking.append(shapely.box(cx - lw / 2, cy - lh / 2, cx + lw / 2, cy + lh / 2))
    # houses with driveways, along every street side, inside blocks
    hs = spec.get("houses", {}) or {}
    spacing = float(hs.get("spacing_m", 22.0))
    setback = float(hs.get("setback_m", 8.0))
    dw = float(hs.get("driveway_width_m", 3.2))
    p_drive = float(hs.get("driveway_prob", 0.8))
    houses = []
    lot_area = shapely.union_all(b.parking).buffer(4.0) if b.parking else shapely.Polygon()
    for r in b.roads:
        if r.dead_end:
            continue
        for sign in (1.0, -1.0):
            edge = r.width_m / 2 + r.sidewalk_m
            front = _offset(r.line, sign * (edge + setback))
            if front.is_empty:
                continue
            s = np.arange(spacing / 2, front.length, spacing)
            for si in s:
                p = front.interpolate(si)
                q = front.interpolate(min(si + 0.5, front.length))
                d = np.array([q.x - p.x, q.y - p.y])
                if np.linalg.norm(d) < 1e-6:
                    continue
                d /= np.linalg.norm(d)
                nrm = np.array([-d[1], d[0]]) * sign  # away from the road
                w = b.rng.uniform(*hs.get("width_m", [10, 15]))
                dep = b.rng.uniform(*hs.get("depth_m", [9, 13]))
                c = np.array([p.x, p.y]) + nrm * (dep / 2)
                ang = np.degrees(np.arctan2(d[1], d[0]))
                poly = affinity.rotate(
                    shapely.box(c[0] - w / 2, c[1] - dep / 2, c[0] + w / 2, c[1] + dep / 2),
                    ang, origin=(c[0], c[1]),
                )
                if poly.buffer(3.0).intersects(ra) or poly.intersects(lot_area):
                    continue
                houses.append((poly, b.rng.uniform(*hs.get("height_m", [5, 9])), p, d, nrm))
    # keep houses that clear the streets, the lots and each other (greedy, seeded order)
    b._blocked = ra.union(lot_area)
    kept = []
    for poly, hgt, p, d, nrm in houses:
        if b.try_building(poly, hgt, clearance=1.0):
            kept.append((p, d, nrm))
    for p, d, nrm in kept:
        if b.rng.random() < p_drive:
            # driveway from the house front to the road edge, beside the house centre
            side_off = b.rng.choice([-1.0, 1.0]) * b.rng.uniform(1.0, 3.0)
            a = np.array([p.x, p.y]) + d * side_off + nrm * 0.5
            e = a - nrm * (setback + side + 1.5)
            b.parking.append(LineString([a, e]).buffer(dw / 2, cap_style="flat"))
    b.freeze_areas()
    t = spec.get("trees", {}) or {}
    row = t.get("street", {}) or {}
    if row:
        for r in b.roads:
            for sign in (1.0, -1.0):
                off = _offset(r.line, sign * (r.width_m / 2 + r.sidewalk_m + float(row.get("offset_m", 1.2))))
                b.add_tree_row(off, float(row.get("spacing_m", 18.0)), row.get("crown_radius_m", [2.5, 4.0]),
                               row.get("height_m", [7, 11]))
    yard = t.get("yard", {}) or {}
    if int(yard.get("count", 0)) > 0:
        free = b.box.difference(b._blocked.buffer(2.0))
        b.add_tree_cluster(int(yard["count"]), free, yard.get("crown_radius_m", [2.0, 4.0]),
                           yard.get("height_m", [5, 10]))
    p = spec.get("poles", {}) or {}
    for r in b.roads:
        if r.width_m >= float(p.get("min_road_width_m", 7.0)):
            b.add_poles_along(r, float(p.get("spacing_m", 40.0)), float(p.get("height_m", 7.0)),
                              r.sidewalk_m + float(p.get("offset_m", 0.5)))


def _gen_highway(b: _Builder, spec: Mapping):
    """Expressway: a curving dual carriageway with at-grade junctions.

    Each carriageway is a one-way road whose line direction is its right-hand traffic
    direction (eastbound south of the grass median, westbound north of it). Two-way crossing
    roads cross both carriageways through an opening in the median (no ramps, no slip
    lanes). Optional two-way local roads run parallel to the highway, far enough out that
    no other road lies within ``local_clear_m`` of a carriageway's outer edge; they meet the
    crossing roads at X-junctions.
    """
    import shapely
    from shapely.geometry import LineString

    hw = spec["highway"]
    W, H = (float(v) for v in spec["size_m"])
    lanes = int(hw.get("lanes", 3))
    lane_w = float(hw.get("lane_width_m", 3.5))
    sh_r = float(hw.get("shoulder_right_m", 2.5))
    sh_l = float(hw.get("shoulder_left_m", 0.75))
    median = float(hw.get("median_m", 8.0))
    if not (0.0 < median):
        raise ValueError(f"highway.median_m must be > 0, got {median}")
    cw = lanes * lane_w + sh_r + sh_l
    amp = float(hw.get("curve_amplitude_m", 30.0))
    xs = np.linspace(-W / 2 - 20.0, W / 2 + 20.0, 97)
    phase = b.rng.uniform(0, 2 * np.pi)
    yc = amp * np.sin(2 * np.pi * xs / W + phase) * np.clip(np.abs(xs) / (0.15 * W), 0, 1)
    base_long = LineString(_chaikin(np.column_stack([xs, yc]), 2))
    base = base_long.intersection(b.box)
    off = median / 2 + cw / 2
    outer = median / 2 + cw  # base line to a carriageway's outer edge
    # right-hand traffic: eastbound carriageway south of the median, westbound north of it
    east = _offset(base_long, -off).intersection(b.box)
    west = _offset(base_long, off).intersection(b.box)
    west = LineString(list(west.coords)[::-1])
    b.roads.append(_Road("eastbound", east, cw, oneway=True, lanes=lanes, shoulder_left_m=sh_l))
    b.roads.append(_Road("westbound", west, cw, oneway=True, lanes=lanes, shoulder_left_m=sh_l))

    def frame_at(x):
        """Point on the base line at x and its unit tangent / left normal."""
        s = base.project(shapely.Point(x, float(np.interp(x, xs, yc))))
        p = np.asarray(base.interpolate(s).coords[0])
        q = np.asarray(base.interpolate(min(s + 1.0, base.length)).coords[0])
        r = np.asarray(base.interpolate(max(s - 1.0, 0.0)).coords[0])
        t = (q - r) / np.linalg.norm(q - r)
        return p, t, np.array([-t[1], t[0]])

    # two-way crossing roads (at-grade junctions): straight and square to the highway within
    # ``straight_m`` of its outer edges, then bending gently away (seeded) to the scene edge.
    jxs = hw.get("junction_x_m", 0.0)
    jxs = [float(v) for v in (jxs if isinstance(jxs, (list, tuple)) else [jxs])]
    cr_w = float(hw.get("crossing_width_m", 9.0))
    straight = outer + float(hw.get("crossing_straight_m", 40.0))
    bend = float(hw.get("crossing_bend_m", 25.0))
    opening = float(hw.get("median_opening_m", cr_w + 4.0))
    crossings, openings = [], []
    for k, jx in enumerate(jxs):
        p, t, nrm = frame_at(jx)
        pts = []
        for side in (-1.0, 1.0):
            drift = b.rng.uniform(-bend, bend)
            far = 1.2 * H
            ds = np.linspace(straight, far, 8)
            lat = drift * ((ds - straight) / (far - straight)) ** 1.5
            pts.append([p + nrm * side * d + t * lat_m for d, lat_m in zip(ds, lat)])
        line_pts = np.vstack([pts[0][::-1], [p], pts[1]])
        line = LineString(_chaikin(line_pts, 2))
        line = line.intersection(b.box)
        if line.geom_type != "LineString":
            raise ValueError(f"crossing road at x={jx} leaves the scene")
        name = "crossing" if k == 0 else f"crossing_{k + 1}"
        cross = _Road(name, line, cr_w, lanes=1)
        b.roads.append(cross)
        crossings.append(cross)
        # median opening: the crossing road plus (opening - width)/2 each side, median only
        if opening > cr_w:
            band = LineString([p - nrm * outer, p + nrm * outer]).buffer(opening / 2, cap_style="flat")
            openings.append(band.intersection(base.buffer(median / 2 + 0.05, cap_style="flat")))
    b.pads.extend(openings)
    # two-way local roads parallel to the highway, clear of its outer edges
    loc = hw.get("local_roads", {}) or {}
    loc_w = float(loc.get("width_m", 7.0))
    clear = float(loc.get("clear_m", 15.0))
    for name, dist in (("local_north", loc.get("north_m")), ("local_south", loc.get("south_m"))):
        if dist is None:
            continue
        dist = float(dist)
        sign = 1.0 if name == "local_north" else -1.0
        wig = float(loc.get("wiggle_m", 0.0))
        o = _offset(base_long, sign * dist)
        o_pts = np.asarray(o.coords)
        o_pts = np.vstack([o_pts[:-1:max(1, len(o_pts) // 16)], o_pts[-1:]])
        o_pts = _wiggle(o_pts, wig, b.rng)
        line = LineString(_chaikin(o_pts, 3)).intersection(b.box)
        if line.geom_type != "LineString":
            raise ValueError(f"{name} leaves the scene more than once")
        # never within ``clear`` of a carriageway's outer edge (plus the half width)
        if line.distance(base) < outer + clear + loc_w / 2:
            raise ValueError(f"{name} comes within {clear} m of the highway")
        b.roads.append(_Road(name, line, loc_w, lanes=1))
    b.freeze_areas()
    # median stays grass (ground); trees and poles beside the highway, a few buildings
    t = spec.get("trees", {}) or {}
    if int(t.get("count", 0)) > 0:
        free = b.box.difference(b._blocked.buffer(6.0))
        b.add_tree_cluster(int(t["count"]), free, t.get("crown_radius_m", [2.5, 5.0]),
                           t.get("height_m", [7, 15]))
    _random_buildings(b, spec.get("buildings", {}) or {})
    p = spec.get("poles", {}) or {}
    if p:
        for cross in crossings:
            b.add_poles_along(cross, float(p.get("spacing_m", 30.0)), float(p.get("height_m", 10.0)),
                              float(p.get("offset_m", 1.0)))
        # lamp posts in the median, between the carriageways (not in the openings)
        s = np.arange(10.0, base.length, float(p.get("median_spacing_m", 50.0)))
        pts = shapely.get_coordinates(shapely.line_interpolate_point(base, s))
        ok = ~shapely.intersects(b._road_prepared(), shapely.points(pts))
        for (x, y), good in zip(pts, ok):
            if good:
                b.poles.append((float(x), float(y), float(p.get("height_m", 10.0))))


GENERATORS = {"city_park": _gen_city_park, "suburb": _gen_suburb, "highway": _gen_highway}


def generate(spec: Mapping, seed: int | None = None, source: str = "") -> Scene:
    """Build a procedural scene from a spec mapping.

    spec : mapping with ``generator`` (city_park | suburb | highway), ``name``, ``seed``,
           ``size_m`` [w, h] and the generator's parameters (see docs/scenes.md)
    seed : overrides ``spec["seed"]`` when given (0 is a valid seed)
    source : provenance string stored in ``Scene.source``
    """
    where = source or "scene spec"
    if not isinstance(spec, Mapping):
        raise SceneError(f"{where}: expected a mapping, got {type(spec).__name__}")
    kind = spec.get("generator")
    if kind not in GENERATORS:
        raise SceneError(
            f"{where}: field 'generator' must be one of {', '.join(GENERATORS)}, got {kind!r}"
        )
    size = spec.get("size_m")
    if not (isinstance(size, (list, tuple)) and len(size) == 2 and all(float(v) > 0 for v in size)):
        raise SceneError(f"{where}: field 'size_m' must be [width, height] in metres, got {size!r}")
    s = spec.get("seed", 0) if seed is None else seed
    try:
        s = int(s)
    except (TypeError, ValueError):
        raise SceneError(f"{where}: field 'seed' must be an integer, got {s!r}") from None
    rng = np.random.default_rng(s)
    name = str(spec.get("name", kind))
    b = _Builder(name, spec, rng)
    try:
        GENERATORS[kind](b, spec)
    except (KeyError, TypeError, ValueError) as exc:
        raise SceneError(f"{where}: bad generator parameter ({type(exc).__name__}: {exc})") from None
    if not b.roads:
        raise SceneError(f"{where}: the spec produced no road")
    meta = {"generator": kind, "seed": s, "size_m": [float(v) for v in size]}
    return b.scene(source or f"procedural:{name}", meta)
