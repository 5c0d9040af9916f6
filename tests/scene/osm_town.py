"""A small hand-written OSM town for the OSM tests (and the docs picture).

Coordinates are written in metres east/north of a reference point and turned into WGS84 with
a local equirectangular approximation; the tests project them back independently with pyproj.
The same definition is written as OSM XML (optionally bzip2) or as PBF (osmium's writer).

Layout (metres, x east, y north), bbox +-300 m:
  main      two-way residential street (lanes=2) along y = 0, x -280 .. 280
  oneway    one-way residential street (oneway=yes, width=6) northbound along x = -100
  dual      dual carriageway: two one-way primary ways (lanes=2), y = -150 eastbound and
            y = -128 westbound (13 m grass median), x -280 .. 180
  ring      roundabout (junction=roundabout, width=7), centre (150, 110), radius 28 m,
            counter-clockwise, with a two-way spur to main street at x = 150
  avenue    lanes=3 one-way primary, southbound along x = 240
  parking   amenity=parking lot west of the one-way street
  buildings with levels, without, with height; a courtyard multipolygon; a lake with an
            island (multipolygon); a park; tree points (one with diameter_crown) and a tree row;
            a footway
"""

from __future__ import annotations

import bz2
import math
from pathlib import Path

LAT0, LON0 = 52.5200, 13.4000
M_PER_DEG_LAT = 111320.0
BBOX_M = 300.0


def to_lonlat(x, y):
    return (LON0 + x / (M_PER_DEG_LAT * math.cos(math.radians(LAT0))), LAT0 + y / M_PER_DEG_LAT)


def bbox_lonlat(half=BBOX_M):
    lo = to_lonlat(-half, -half)
    hi = to_lonlat(half, half)
    return (lo[0], lo[1], hi[0], hi[1])


class Town:
    """Nodes {id: (x, y, tags)}, ways {id: (node ids, tags)}, relations {id: (members, tags)}."""

    def __init__(self):
        self.nodes: dict[int, tuple] = {}
        self.ways: dict[int, tuple] = {}
        self.relations: dict[int, tuple] = {}
        self._nid = 1
        self._wid = 1
        self._where: dict[tuple, int] = {}

    def node(self, x, y, tags=None, shared=True):
        key = (round(x, 3), round(y, 3))
        if shared and key in self._where and not tags:
            return self._where[key]
        nid = self._nid
        self._nid += 1
        self.nodes[nid] = (float(x), float(y), dict(tags or {}))
        if shared:
            self._where[key] = nid
        return nid

    def way(self, pts, tags, close=False):
        ids = [self.node(x, y) for x, y in pts]
        if close:
            ids.append(ids[0])
        wid = self._wid
        self._wid += 1
        self.ways[wid] = (ids, dict(tags))
        return wid

    def relation(self, members, tags):
        rid = len(self.relations) + 1
        self.relations[rid] = (members, dict(tags))
        return rid

    # ------------------------------------------------------------------ writers
    def xml(self, with_bounds=True) -> str:
        from xml.sax.saxutils import quoteattr

        def tags(t):
            return "".join(f'<tag k={quoteattr(k)} v={quoteattr(str(v))}/>' for k, v in t.items())

        out = ['<?xml version="1.0" encoding="UTF-8"?>',
               '<osm version="0.6" generator="aerial-synth tests">']
        if with_bounds:
            b = bbox_lonlat()
            out.append(f'<bounds minlon="{b[0]:.7f}" minlat="{b[1]:.7f}" maxlon="{b[2]:.7f}" '
                       f'maxlat="{b[3]:.7f}"/>')
        for nid, (x, y, t) in sorted(self.nodes.items()):
            lon, lat = to_lonlat(x, y)
            out.append(f'<node id="{nid}" version="1" lat="{lat:.7f}" lon="{lon:.7f}">'
                       f'{tags(t)}</node>')
        for wid, (ids, t) in sorted(self.ways.items()):
            nds = "".join(f'<nd ref="{i}"/>' for i in ids)
            out.append(f'<way id="{wid}" version="1">{nds}{tags(t)}</way>')
        for rid, (members, t) in sorted(self.relations.items()):
            ms = "".join(f'<member type="{ty}" ref="{ref}" role="{role}"/>'
                         for ty, ref, role in members)
            out.append(f'<relation id="{rid}" version="1">{ms}{tags(t)}</relation>')
        out.append("</osm>")
        return "\n".join(out) + "\n"

    def write(self, path) -> Path:
        path = Path(path)
        name = path.name.lower()
        if name.endswith(".pbf"):
            self.write_pbf(path)
        elif name.endswith(".bz2"):
            path.write_bytes(bz2.compress(self.xml().encode()))
        else:
            path.write_text(self.xml(), encoding="utf-8")
        return path

    def write_pbf(self, path) -> Path:
        import osmium

        path = Path(path)
        if path.exists():
            path.unlink()
        w = osmium.SimpleWriter(str(path))
        try:
            for nid, (x, y, t) in sorted(self.nodes.items()):
                w.add_node(osmium.osm.mutable.Node(id=nid, location=to_lonlat(x, y), tags=t,
                                                   version=1))
            for wid, (ids, t) in sorted(self.ways.items()):
                w.add_way(osmium.osm.mutable.Way(id=wid, nodes=ids, tags=t, version=1))
            for rid, (members, t) in sorted(self.relations.items()):
                w.add_relation(osmium.osm.mutable.Relation(id=rid, members=members, tags=t,
                                                           version=1))
        finally:
            w.close()
        return path


def circle(cx, cy, r, n, start_deg=0.0):
    """n points counter-clockwise on a circle."""
    return [(cx + r * math.cos(math.radians(start_deg + 360.0 * k / n)),
             cy + r * math.sin(math.radians(start_deg + 360.0 * k / n))) for k in range(n)]


def rect(x0, y0, x1, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def make_town() -> Town:
    t = Town()
    # main street: two-way, crossed by the one-way street, the spur and the avenue
    xs = [-280, -200, -100, 0, 60, 150, 240, 280]
    t.way([(x, 0) for x in xs], {"highway": "residential", "lanes": "2", "name": "Main Street"})
    # one-way street, northbound, crossing main street at (-100, 0)
    t.way([(-100, y) for y in (-100, -50, 0, 50, 150, 280)],
          {"highway": "residential", "oneway": "yes", "width": "6", "name": "Oneway Lane"})
    # dual carriageway: eastbound (south) and westbound (north), median 13 m of grass
    t.way([(x, -150) for x in (-280, -180, -80, 20, 120, 180)],
          {"highway": "primary", "oneway": "yes", "lanes": "2", "name": "Dual East"})
    t.way([(x, -128) for x in (180, 120, 20, -80, -180, -280)],
          {"highway": "primary", "oneway": "yes", "lanes": "2", "name": "Dual West"})
    t.way(rect(-280, -146.5, 180, -131.5), {"landuse": "grass"}, close=True)
    # roundabout (counter-clockwise for right-hand traffic) and its spur to main street
    ring = circle(150, 110, 28, 24, start_deg=-90.0)  # first node at (150, 82)
    t.way(ring, {"highway": "residential", "junction": "roundabout", "width": "7",
                 "name": "Ring"}, close=True)
    t.way([(150, 0), (150, 40), (150, 82)], {"highway": "residential", "name": "Spur"})
    # lanes=3 one-way avenue, southbound
    t.way([(240, y) for y in (280, 150, 0, -100, -280)],
          {"highway": "primary", "oneway": "yes", "lanes": "3", "name": "Avenue"})
    # parking lot west of the one-way street
    t.way(rect(-210, 30, -130, 90), {"amenity": "parking", "parking": "surface"}, close=True)
    t.way([(-130, 60), (-115, 55), (-100, 50)], {"highway": "service", "service": "driveway"})
    # buildings: with levels, without, with height
    t.way(rect(-60, 20, -20, 45), {"building": "apartments", "building:levels": "5"}, close=True)
    t.way(rect(-60, -45, -35, -20), {"building": "house"}, close=True)
    t.way(rect(60, 20, 100, 50), {"building": "yes", "height": "12.5"}, close=True)
    # courtyard building (multipolygon relation with an inner ring)
    outer = t.way(rect(0, 60, 50, 110), {}, close=True)
    inner = t.way(rect(15, 75, 35, 95), {}, close=True)
    t.relation([("w", outer, "outer"), ("w", inner, "inner")],
               {"type": "multipolygon", "building": "yes", "building:levels": "4"})
    # lake with an island (multipolygon) and a park
    lake = t.way(circle(-20, -70, 30, 20), {}, close=True)
    island = t.way(circle(-20, -70, 8, 10), {}, close=True)
    t.relation([("w", lake, "outer"), ("w", island, "inner")],
               {"type": "multipolygon", "natural": "water"})
    t.way(rect(-280, 170, -130, 280), {"leisure": "park"}, close=True)
    # trees: points (one with a crown diameter) and a row along main street
    t.node(-200, 200, {"natural": "tree", "diameter_crown": "9", "height": "14"}, shared=False)
    t.node(-170, 240, {"natural": "tree"}, shared=False)
    t.node(-240, 220, {"natural": "tree"}, shared=False)
    t.way([(-60, 12), (40, 12)], {"natural": "tree_row"})
    # a footway beside main street
    t.way([(-80, -7), (120, -7)], {"highway": "footway"})
    return t


#: (name, osm way id) of the roads, for the tests
def road_ids(town: Town) -> dict[str, int]:
    return {t.get("name"): wid for wid, (_, t) in town.ways.items() if t.get("name")}
