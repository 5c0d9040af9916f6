"""Streaming OSM reader: one pyosmium pass, only the features a scene needs, inside a bbox.

pyosmium reads ``.osm``, ``.osm.bz2``, ``.osm.gz`` and ``.osm.pbf``. A ``FileProcessor`` with
a node-location index gives ways their coordinates; its area assembler turns closed ways and
multipolygon relations (courtyards, lakes with islands) into areas. A C++ key filter drops
every object without an interesting key before Python sees it, and candidates are tested
against the bbox in batches, so memory holds the location index and what lies in the bbox,
never the whole file.

Coordinates stay WGS84 longitude/latitude here; :mod:`.build` projects them.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import SceneError
from .tags import area_kind, road_class, waterway_width_m

__all__ = ["OsmData", "read_osm", "OSM_SUFFIXES", "is_osm_path"]

#: File name endings read as OSM data.
OSM_SUFFIXES = (".osm", ".osm.bz2", ".osm.gz", ".osm.pbf", ".pbf")

#: without a bbox or file bounds, the scene covers the data's extent plus this, metres
EXTENT_MARGIN_M = 25.0
#: keys an area (closed way or multipolygon) needs to be looked at
_AREA_KEYS = ("highway", "building", "natural", "landuse", "amenity", "leisure", "water",
              "waterway")
#: keys a (line) way needs: roads and paths, tree rows, rivers
_WAY_KEYS = ("highway", "natural", "waterway")
#: a building whose first node lies further than this outside the bbox is skipped before its
#: geometry is made (degrees; buildings are far smaller)
_BUILDING_REACH_DEG = 0.004
#: the tags a building keeps (they set its height)
_BUILDING_TAGS = ("building", "height", "building:levels", "roof:levels", "name")
_FLUSH = 20000


def is_osm_path(path) -> bool:
    """True when ``path`` names an OSM file by its ending."""
    name = str(path).lower()
    return any(name.endswith(s) for s in OSM_SUFFIXES)


@dataclass
class OsmData:
    """What the reader kept (WGS84 lon/lat).

    lines : list of (kind, osm id, tags dict, shapely LineString); kind is road, sidewalk,
            tree_row or waterway
    areas : list of (kind, area id, tags dict, shapely (Multi)Polygon); kind from
            :func:`.tags.area_kind`
    trees : list of (osm id, lon, lat, tags dict)
    bbox  : (minlon, minlat, maxlon, maxlat) actually used
    counts: objects seen by Python per type
    """

    lines: list = field(default_factory=list)
    areas: list = field(default_factory=list)
    trees: list = field(default_factory=list)
    bbox: tuple | None = None
    counts: dict = field(default_factory=dict)

    @property
    def empty(self) -> bool:
        return not (self.lines or self.areas or self.trees)


def _fmt(path: Path) -> str:
    n = path.name.lower()
    for s, f in ((".osm.pbf", "PBF"), (".pbf", "PBF"), (".osm.bz2", "OSM XML (bzip2)"),
                 (".osm.gz", "OSM XML (gzip)"), (".osm", "OSM XML")):
        if n.endswith(s):
            return f
    return "OSM"


class _Batch:
    """Pending candidates, tested against the bbox in one vectorised call per batch."""

    def __init__(self, bbox_poly, out: list):
        self.bbox_poly = bbox_poly
        self.out = out
        self.items: list = []
        self.wkb: list = []

    def add(self, item, wkb) -> None:
        self.items.append(item)
        self.wkb.append(wkb)
        if len(self.wkb) >= _FLUSH:
            self.flush()

    def flush(self) -> None:
        import shapely

        if not self.wkb:
            return
        geoms = shapely.from_wkb(self.wkb, on_invalid="ignore")
        ok = ~shapely.is_missing(geoms)
        if self.bbox_poly is not None:
            ok &= shapely.intersects(geoms, self.bbox_poly)
        for i in np.flatnonzero(ok):
            kind, oid, tags = self.items[i]
            self.out.append((kind, oid, tags, geoms[i]))
        self.items, self.wkb = [], []


def _way_wkb(fab, way) -> bytes | None:
    """WKB of a way's line; with nodes missing from the extract, the part that is there."""
    import osmium
    import shapely

    try:
        return fab.create_linestring(way)
    except (osmium.InvalidLocationError, RuntimeError):
        pts = [(n.lon, n.lat) for n in way.nodes if n.location.valid()]
        if len(pts) < 2:
            return None
        return shapely.to_wkb(shapely.linestrings(pts))


def _first_point(wkb_hex: str) -> tuple[float, float]:
    """(lon, lat) of the first point of osmium's hex WKB MultiPolygon (little endian:
    byte order, type, polygon count, byte order, type, ring count, point count, then x, y)."""
    if wkb_hex[:2] == "01" and wkb_hex[18:20] == "01":
        return struct.unpack("<dd", bytes.fromhex(wkb_hex[44:76]))
    import shapely  # any other layout: let shapely read it

    x, y = shapely.get_coordinates(shapely.from_wkb(wkb_hex))[0]
    return float(x), float(y)


class _Collector:
    """pyosmium handler: called from C++ only for objects that passed the key filters."""

    def __init__(self, data: OsmData, bbox, lines: _Batch, areas: _Batch):
        import osmium.geom

        self.data, self.bbox, self.lines, self.areas = data, bbox, lines, areas
        self.fab = osmium.geom.WKBFactory()
        self.counts = {"nodes": 0, "ways": 0, "areas": 0}
        self.negative = 0  # ways left without geometry whose node ids are negative
        if bbox is not None:
            r = _BUILDING_REACH_DEG
            self.reach = (bbox[0] - r, bbox[1] - r, bbox[2] + r, bbox[3] + r)

    def node(self, obj) -> None:
        self.counts["nodes"] += 1
        if obj.tags.get("natural") != "tree":
            return
        loc = obj.location
        if not loc.valid():
            return
        lon, lat = loc.lon, loc.lat
        b = self.bbox
        if b is not None and not (b[0] <= lon <= b[2] and b[1] <= lat <= b[3]):
            return
        self.data.trees.append((obj.id, lon, lat, dict(obj.tags)))

    def way(self, obj) -> None:
        self.counts["ways"] += 1
        tags = obj.tags
        kind = road_class(tags)
        if kind is None:
            if tags.get("natural") == "tree_row":
                kind = "tree_row"
            elif "waterway" in tags and waterway_width_m(tags) is not None:
                kind = "waterway"
            else:
                return
        wkb = _way_wkb(self.fab, obj)
        if wkb is not None:
            self.lines.add((kind, obj.id, dict(tags)), wkb)
        elif len(obj.nodes) and obj.nodes[0].ref < 0:
            self.negative += 1

    def area(self, obj) -> None:
        import osmium

        self.counts["areas"] += 1
        kind = area_kind(obj.tags)
        if kind is None:
            return
        try:
            wkb = self.fab.create_multipolygon(obj)
        except (osmium.InvalidLocationError, RuntimeError):
            return
        if kind == "building":
            if self.bbox is not None:
                lon, lat = _first_point(wkb)
                r = self.reach
                if not (r[0] <= lon <= r[2] and r[1] <= lat <= r[3]):
                    return
            tg = obj.tags
            tags = {k: tg.get(k) for k in _BUILDING_TAGS if k in tg}
        else:
            tags = dict(obj.tags)
        self.areas.add((kind, obj.id, tags), wkb)


def read_osm(path: str | Path, bbox: tuple | None = None) -> OsmData:
    """Read the scene features of an OSM file, keeping those that intersect ``bbox``.

    bbox : (minlon, minlat, maxlon, maxlat) WGS84, or None for everything (then the file's
           own bounds, else the extent of what was read, become ``OsmData.bbox``)
    Raises :class:`SceneError` (one line) for a missing, unreadable, malformed or truncated
    file.

    Two passes with ``osmium.apply``: relations (multipolygon candidates), then everything
    with a node-location index; areas are handed on as the assembler completes them, so
    nothing piles up in a buffer. C++ filters let only tree nodes, road/path/tree-row/river
    ways and areas with a key we use reach Python (building ways come once, as areas).
    """
    import osmium
    import osmium.area
    import osmium.filter
    import osmium.index
    import shapely

    path = Path(path)
    if not path.is_file():
        raise SceneError(f"OSM file {path}: file not found")
    fmt = _fmt(path)
    bbox_poly = shapely.box(*bbox) if bbox is not None else None
    if bbox_poly is not None:
        shapely.prepare(bbox_poly)
    data = OsmData(bbox=tuple(bbox) if bbox is not None else None)
    lines = _Batch(bbox_poly, data.lines)
    areas = _Batch(bbox_poly, data.areas)
    col = _Collector(data, bbox, lines, areas)
    header_box = None
    osm, flt = osmium.osm, osmium.filter
    try:
        rd = osmium.io.Reader(str(path), osm.NOTHING)
        try:
            hb = rd.header().box()
        finally:
            rd.close()
        if hb.valid():
            header_box = (hb.bottom_left.lon, hb.bottom_left.lat, hb.top_right.lon,
                          hb.top_right.lat)
        am = osmium.area.AreaManager()
        rd = osmium.io.Reader(str(path), osm.RELATION)
        try:
            osmium.apply(rd, flt.KeyFilter(*_AREA_KEYS), am.first_pass_handler())
        finally:
            rd.close()
        lh = osmium.NodeLocationsForWays(osmium.index.create_map("flex_mem"))
        lh.ignore_errors()
        osmium.apply(
            str(path),
            lh,
            am.second_pass_handler(flt.KeyFilter(*_AREA_KEYS), col),
            flt.EntityFilter(osm.NODE | osm.WAY),
            flt.KeyFilter("natural").enable_for(osm.NODE),
            flt.KeyFilter(*_WAY_KEYS).enable_for(osm.WAY),
            col,
        )
        lines.flush()
        areas.flush()
    except SceneError:
        raise
    except Exception as exc:  # osmium reports malformed/truncated input as RuntimeError etc.
        msg = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise SceneError(f"OSM file {path}: cannot read as {fmt} ({msg})") from None
    counts = col.counts
    if col.negative and not data.lines:
        raise SceneError(
            f"OSM file {path}: its ways use negative node ids (unsaved JOSM/iD data), which "
            f"the node-location index cannot hold; expected positive ids (upload or renumber "
            f"the data first, e.g. with 'osmium renumber')"
        )
    data.counts = counts
    if data.bbox is None:
        if header_box is not None:
            data.bbox = header_box
        elif not data.empty:
            geoms = [g for *_, g in data.lines] + [g for *_, g in data.areas]
            b = shapely.total_bounds(np.array(geoms, dtype=object)) if geoms else None
            pts = np.array([[lon, lat] for _, lon, lat, _ in data.trees]).reshape(-1, 2)
            lo = [b[:2]] if b is not None else []
            hi = [b[2:]] if b is not None else []
            if len(pts):
                lo.append(pts.min(0))
                hi.append(pts.max(0))
            lo, hi = np.min(lo, axis=0), np.max(hi, axis=0)
            # a margin, so roads on the edge of the data stay whole (not cut lengthwise)
            dy = EXTENT_MARGIN_M / 111320.0
            dx = dy / max(0.05, float(np.cos(np.radians((lo[1] + hi[1]) / 2))))
            data.bbox = (float(lo[0] - dx), float(max(-85.0, lo[1] - dy)), float(hi[0] + dx),
                         float(min(85.0, hi[1] + dy)))
    return data
