"""Scene assembly for the procedural generators.

:class:`Builder` collects road centre lines, parking, water, buildings, trees and poles,
answers placement questions (is this spot free?) and finally emits the labelled objects
and the ground truth. Heights: ground 0.0, road and parking 0.05, lane markings 0.06,
sidewalks raised 0.12. Ground covers the whole scene except water (the only other surface
at its height), so it lies 5 cm under roads and parking and catches any ray that slips
past their edges.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ..build import cylinder, ellipsoid, merge_meshes, polygon_object, prism
from ..model import LabelConfig, RoadTruth, Scene, SceneObject, SceneTruth
from .markings import road_markings
from .roads import Road, offset_line, polygonal, road_polygon

__all__ = ["Builder", "Z_GROUND", "Z_ROAD", "Z_MARKING", "Z_SIDEWALK"]

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


# --------------------------------------------------------------------------- assembly
class Builder:
    """Collects polygons and meshes, then emits labelled objects and truth."""

    def __init__(self, name: str, spec: Mapping, rng: np.random.Generator):
        import shapely

        self.name = name
        self.spec = spec
        self.rng = rng
        w, h = (float(v) for v in spec["size_m"])
        self.box = shapely.box(-w / 2, -h / 2, w / 2, h / 2)
        self.roads: list[Road] = []
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
            polys = [road_polygon(r) for r in self.roads]
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

    def add_poles_along(self, r: Road, spacing_m: float, height_m: float, side_offset_m: float):
        import shapely

        for sign in (1.0, -1.0):
            off = offset_line(r.line, sign * (r.width_m / 2 + side_offset_m))
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

        # Ground lies under roads and parking too (holes only for water, at the same height):
        # a camera ray that slips between two surfaces or past a road's 5 cm edge at an
        # angle then lands on ground instead of leaving the scene (about 100-500 such rays
        # per 1024 x 1024 frame before; tools/crack_count.py).
        ground = polygonal(self.box.difference(water))
        objs.append(polygon_object("ground", "ground", ground, Z_GROUND))
        for i, part in enumerate(shapely.get_parts(road_area)):
            objs.append(polygon_object(f"road_{i:03d}", "road", part, Z_ROAD))
        if not parking.is_empty:
            objs.append(polygon_object("parking", "parking", parking, Z_ROAD))
        lot_marks = getattr(self, "lot_markings", None)  # painted bays (procedural/parking.py)
        if lot_marks and not parking.is_empty:
            pm = polygonal(shapely.union_all(lot_marks).intersection(parking))
            if not pm.is_empty:
                objs.append(polygon_object("parking_marking", "parking_marking", pm, Z_MARKING))
        if getattr(self, "parking_hints", None):
            meta = {**meta, "parking_lots": self.parking_hints}
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
                m = polygonal(road_markings(r, others_area, mcfg).intersection(road_area))
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


