"""Scene assembly for the procedural generators.

:class:`Builder` collects road centre lines, parking, water, buildings, trees and poles,
answers placement questions (is this spot free?) and finally emits the labelled objects
and the ground truth. Heights: ground 0.0, road and parking 0.05, tyre tracks 0.055, lane markings 0.06,
sidewalks raised 0.12. Ground covers the whole scene except water (the only other surface
at its height), so it lies 5 cm under roads and parking and catches any ray that slips
past their edges.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ..build import cylinder, merge_meshes, polygon_object, prism
from ..model import LabelConfig, RoadTruth, Scene, SceneObject, SceneTruth
from ..scene_hints import LotHint, SceneHints
from .markings import TRACK_DEFAULTS, road_markings, road_tracks
from .roads import Road, offset_line, polygonal, road_polygon
from .roofs import building_objects
from .trees import DEFAULT_SPECIES, draw_species, species_weights, tree_objects

__all__ = ["Builder", "Z_GROUND", "Z_ROAD", "Z_TRACK", "Z_MARKING", "Z_SIDEWALK"]

Z_GROUND = 0.0
Z_ROAD = 0.05
Z_MARKING = 0.06
#: Tyre tracks: 5 mm above the asphalt, under the markings (coplanar offset like them).
Z_TRACK = 0.055
Z_SIDEWALK = 0.12



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
        # x, y, crown r, height, species index, shape u, colour number (procedural/trees.py)
        self.trees: list[tuple[float, ...]] = []
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

    def add_tree_row(self, line, spacing_m, crown_r, height, trunk_frac=0.4, jitter_m=0.5,
                     species=None):
        """Trees along a line (shapely); crowns may overhang, trunks must be clear.
        species: {name: weight} (procedural/trees.py), None = the scene's mix."""
        import shapely

        L = line.length
        if L < spacing_m:
            return
        s = np.arange(spacing_m / 2, L, spacing_m)
        pts = shapely.get_coordinates(shapely.line_interpolate_point(line, s))
        pts = pts + self.rng.uniform(-jitter_m, jitter_m, pts.shape)
        self._add_trees(pts, crown_r, height, trunk_frac, species)

    def add_tree_cluster(self, n, region, crown_r, height, trunk_frac=0.4, species=None):
        """n random trees in a shapely region."""
        import shapely

        minx, miny, maxx, maxy = region.bounds
        pts = np.column_stack(
            [self.rng.uniform(minx, maxx, 4 * n), self.rng.uniform(miny, maxy, 4 * n)]
        )
        inside = shapely.contains(region, shapely.points(pts))
        self._add_trees(pts[inside][:n], crown_r, height, trunk_frac, species)

    def species_weights(self, species=None) -> np.ndarray:
        """Species probabilities: ``species`` if given, else the spec's ``tree_species``,
        else the generator's default mix (procedural/trees.py)."""
        if species is None:
            species = self.spec.get("tree_species")
        if species is None:
            species = DEFAULT_SPECIES.get(str(self.spec.get("generator")), {"broadleaf": 1.0})
        return species_weights(species)

    def _add_trees(self, pts, crown_r, height, trunk_frac, species=None):
        """Trees at pts whose trunks stand clear; trunk_frac is kept for callers (the crown
        shape now follows the species, procedural/trees.py)."""
        if len(pts) == 0:
            return
        n = len(pts)
        r = self.rng.uniform(crown_r[0], crown_r[1], n)
        h = self.rng.uniform(height[0], height[1], n)
        sp, u = draw_species(self.rng, n, self.species_weights(species))
        cu = self.rng.random(n)
        ok = self.trunk_ok(pts, 0.6)
        for (x, y), rr, hh, s, uu, cc, good in zip(pts, r, h, sp, u, cu, ok):
            if good:
                self.trees.append((float(x), float(y), float(rr), float(hh), float(s), float(uu), float(cc)))

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
        lot_hints = tuple(LotHint.from_dict(h, f"scene {self.name}: lot hint")
                          for h in getattr(self, "parking_hints", None) or ())
        if not water.is_empty:
            objs.append(polygon_object("water_lake", "water", water, Z_GROUND))
        if not sidewalk.is_empty:
            v, f = prism(sidewalk, Z_GROUND, Z_SIDEWALK)
            objs.append(SceneObject("sidewalk", "sidewalk", v, f))
        mcfg = self.spec.get("markings", {}) or {}
        tcfg = {**TRACK_DEFAULTS, **(self.spec.get("tracks", {}) or {})}
        lane_w = float(mcfg.get("lane_width_m", 3.5))
        # The junction clearance only looks at the other surfaces within reach of a road: the
        # others are clipped to its neighbourhood (round-capped, ``clear + 1`` m wider than
        # the road) before the buffer; a clip edge then stays > clear + 1 m from the road's
        # own surface, so the clearance on it is exactly that of the whole union (and the
        # cost no longer grows with the square of the number of roads).
        surfaces = list(self._road_polys) + list(self.pads)
        tree = shapely.STRtree(surfaces)
        reach = 1.0 + max(float(mcfg.get("junction_clear_m", 1.5)), float(tcfg["junction_clear_m"]))
        for i, r in enumerate(self.roads):
            if not (mcfg.get("enabled", True) or tcfg["enabled"]):
                break
            near = r.line.buffer(r.width_m / 2 + reach)
            others = [surfaces[j] for j in sorted(tree.query(near, predicate="intersects")) if j != i]
            others_area = shapely.union_all(others).intersection(near) if others else None
            if tcfg["enabled"]:
                # worn wheel paths: road label (drivable), 'track' material, 5 mm up
                t = polygonal(road_tracks(r, others_area, tcfg, lane_w).intersection(road_area))
                if not t.is_empty:
                    objs.append(polygon_object(f"track_{r.name}", "road", t, Z_TRACK, material="track"))
            if mcfg.get("enabled", True):
                m = polygonal(road_markings(r, others_area, mcfg).intersection(road_area))
                if not m.is_empty:
                    objs.append(polygon_object(f"lane_marking_{r.name}", "lane_marking", m, Z_MARKING))
        # buildings with roof coverings and roof details, each from a seed of its own
        seeds = self.rng.integers(2**62, size=len(self.buildings))
        objs.extend(building_objects(self.buildings, seeds, self.spec))
        # trees: clumped crowns grouped by species and colour, one trunk object
        if self.trees:
            objs.extend(tree_objects(np.asarray(self.trees, float),
                                     sub=int(self.spec.get("tree_subdivisions", 0))))
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
            hints=SceneHints(lots=lot_hints),
        )


