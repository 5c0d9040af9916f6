"""Generator ``city_park``: explicit curved roads, lakes, buildings, tree rows and a park."""

from __future__ import annotations

from typing import Mapping

from .builder import Builder
from .features import lake, random_buildings, spec_roads
from .generators import Generator
from .roads import offset_line


def generate_city_park(b: Builder, spec: Mapping):
    spec_roads(b, spec.get("roads", []), 8.0)
    for lk in spec.get("lakes", []) or []:
        lake(b, lk)
    b.freeze_areas()
    random_buildings(b, spec.get("buildings", {}) or {})
    t = spec.get("trees", {}) or {}
    row = t.get("rows", {}) or {}
    for r in b.roads:
        if r.name in set(row.get("roads", [])):
            for sign in (1.0, -1.0):
                off = offset_line(r.line, sign * (r.width_m / 2 + r.sidewalk_m + float(row.get("offset_m", 2.5))))
                b.add_tree_row(
                    off, float(row.get("spacing_m", 12.0)), row.get("crown_radius_m", [3.5, 5.0]),
                    row.get("height_m", [9, 14]), species=row.get("species"),
                )
    cl = t.get("park", {}) or {}
    if int(cl.get("count", 0)) > 0:
        free = b.box.difference(b._blocked.buffer(3.0))
        b.add_tree_cluster(int(cl["count"]), free, cl.get("crown_radius_m", [2.5, 5.5]),
                           cl.get("height_m", [6, 16]), species=cl.get("species"))
    p = spec.get("poles", {}) or {}
    for r in b.roads:
        if r.width_m >= float(p.get("min_road_width_m", 8.0)):
            b.add_poles_along(r, float(p.get("spacing_m", 35.0)), float(p.get("height_m", 8.0)),
                              r.sidewalk_m + float(p.get("offset_m", 0.6)))


GENERATOR = Generator("city_park", generate_city_park)
