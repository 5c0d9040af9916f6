"""The road surface of an OSM scene: carriageways unioned into one surface, lane markings,
tyre tracks and junctions (local frame, metres, x east / y north).

Part of :mod:`aerial_synth.scene.osm.build`.
"""

from __future__ import annotations

import numpy as np

from .tags import EDGE_LINE_CLASSES, UNMARKED_CLASSES

__all__ = ["OsmRoad", "road_surface", "road_markings", "tyre_tracks", "find_junctions"]

#: tyre tracks (as procedural/markings.py): strip width, centre distance, extra junction clearance
TRACK_W_M, TRACK_GAUGE_M, TRACK_JUNCTION_M = 0.6, 1.8, 2.0

#: morphological closing radius of the road surface (fills slivers and cracks in junctions)
CLOSE_M = 0.5
#: holes in the road surface thinner than this (metres) are filled
SLIVER_M = 1.0
MARKING_W_M = 0.15
CENTRE_DASH = (3.0, 6.0)
DIVIDER_DASH = (3.0, 9.0)
EDGE_INSET_M = 0.3
JUNCTION_CLEAR_M = 2.0
MIN_CENTRE_LINE_WIDTH_M = 5.0

class OsmRoad:
    """One drivable way's part: its OSM id and tags, :func:`~.tags.road_params`, its centre
    line (local frame, metres; running in its driving direction) and display name."""

    __slots__ = ("osm_id", "tags", "p", "line", "name")

    def __init__(self, osm_id, tags, p, line):
        self.osm_id = osm_id
        self.tags = tags
        self.p = p
        self.line = line
        self.name = str(tags.get("name") or tags.get("ref") or p.cls)


def _fill_slivers(poly):
    """Remove holes thinner than SLIVER_M (cracks between way polygons)."""
    import shapely
    from shapely.geometry import MultiPolygon, Polygon

    out = []
    for part in shapely.get_parts(poly):
        holes = [shapely.Polygon(r) for r in part.interiors]
        if holes:
            thin = shapely.is_empty(shapely.buffer(np.array(holes, dtype=object), -SLIVER_M / 2))
            keep = [h.exterior.coords for h, t in zip(holes, thin) if not t]
            part = Polygon(part.exterior.coords, keep)
        out.append(part)
    return out[0] if len(out) == 1 else MultiPolygon(out)


def road_surface(lines, widths, clip=None):
    """Union of the buffered centre lines (round caps and joins), closed by CLOSE_M and with
    sliver holes filled, clipped to ``clip``. One connected, crack-free network per component.
    """
    import shapely

    bufs = shapely.buffer(np.asarray(lines, dtype=object), np.asarray(widths, float) / 2,
                          quad_segs=6)
    area = shapely.union_all(bufs)
    if CLOSE_M > 0:
        area = shapely.buffer(shapely.buffer(area, CLOSE_M, quad_segs=4), -CLOSE_M, quad_segs=4)
    area = _fill_slivers(area)
    if clip is not None:
        area = shapely.intersection(area, clip)
    return shapely.make_valid(area) if not area.is_valid else area


def _dashes(curves, dash: float, gap: float):
    """Straight chords [s, s + dash] every dash + gap metres along each curve."""
    import shapely

    parts = shapely.get_parts(np.asarray(curves, dtype=object))
    parts = parts[shapely.get_type_id(parts) == 1] if len(parts) else parts
    if not len(parts):
        return np.array([], dtype=object)
    L = shapely.length(parts)
    period = dash + gap
    counts = np.maximum(np.floor((L - dash) / period).astype(int) + 1, 0)
    counts[L < dash] = 0
    if counts.sum() == 0:
        return np.array([], dtype=object)
    idx = np.repeat(np.arange(len(parts)), counts)
    k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    phase = (L - (counts - 1) * period - dash) / 2  # centre the pattern on the curve
    s0 = phase[idx] + k * period
    a = shapely.get_coordinates(shapely.line_interpolate_point(parts[idx], s0))
    b = shapely.get_coordinates(shapely.line_interpolate_point(parts[idx], s0 + dash))
    return shapely.linestrings(np.stack([a, b], axis=1))


def road_markings(roads: list[OsmRoad], road_area, junctions):
    """Centre lines (two-way), lane dividers (from lanes), edge lines (motorway/trunk),
    cleared in junctions and kept inside the road surface."""
    import shapely

    dashed = {CENTRE_DASH: ([], []), DIVIDER_DASH: ([], [])}
    solid_l, solid_o = [], []
    for r in roads:
        p = r.p
        w, n = p.width_m, p.marking_lanes
        if p.cls not in UNMARKED_CLASSES and n >= 2:
            # lane boundaries k = 1 .. n-1 counted from the left edge (line direction); on a
            # two-way road boundary kc (after the backward lanes) is the centre line
            kc = -1 if p.oneway else (p.lanes_backward if p.lanes_backward > 0 else n // 2)
            for k in range(1, n):
                off = w / 2 - k * w / n  # > 0: left of the line's direction
                if k == kc:
                    if w < MIN_CENTRE_LINE_WIDTH_M:
                        continue  # a narrow two-way street: no centre line
                    style = CENTRE_DASH
                else:
                    style = DIVIDER_DASH
                dashed[style][0].append(r.line)
                dashed[style][1].append(off)
        if p.cls in EDGE_LINE_CLASSES and w > 2 * EDGE_INSET_M + 1.0:
            for off in (w / 2 - EDGE_INSET_M, -(w / 2 - EDGE_INSET_M)):
                solid_l.append(r.line)
                solid_o.append(off)
    pieces = []
    for (dash, gap), (ls, offs) in dashed.items():
        if ls:
            curves = shapely.offset_curve(np.array(ls, dtype=object), np.array(offs), quad_segs=4)
            segs = _dashes(curves, dash, gap)
            if len(segs):
                pieces.append(shapely.buffer(segs, MARKING_W_M / 2, cap_style="flat"))
    if solid_l:
        curves = shapely.offset_curve(np.array(solid_l, dtype=object), np.array(solid_o),
                                      quad_segs=4)
        pieces.append(shapely.buffer(curves, MARKING_W_M / 2, cap_style="flat", quad_segs=2))
    if not pieces:
        return np.array([], dtype=object)
    polys = np.concatenate(pieces)
    return _clip_to_road(polys, road_area, junctions)


def _clip_to_road(polys, road_area, junctions, junction_extra_m: float = 0.0):
    """The non-empty polygons of ``polys`` cut to the road surface (inset by half the edge
    inset) minus the junction disks grown by ``junction_extra_m``; polygons wholly inside
    are kept as they are."""
    import shapely

    polys = polys[~shapely.is_empty(polys)]
    clip = shapely.buffer(road_area, -EDGE_INSET_M / 2)
    if len(junctions):
        disks = shapely.buffer(shapely.points(junctions[:, :2]), junctions[:, 2] + junction_extra_m)
        clip = shapely.difference(clip, shapely.union_all(disks))
    shapely.prepare(clip)
    inside = shapely.contains_properly(clip, polys)
    rest = polys[~inside]
    if len(rest):
        rest = shapely.get_parts(shapely.intersection(rest, clip))
        rest = rest[shapely.get_type_id(rest) == 3]
    return np.concatenate([polys[inside], rest])


def tyre_tracks(roads: list[OsmRoad], road_area, junctions):
    """Two worn wheel paths per lane (0.6 m wide, centres 1.8 m apart, centred on the lane)
    of every road with lanes at least 2.4 m wide, kept 2 m further out of junctions than the
    markings and inside the road surface."""
    import shapely

    ls, offs = [], []
    for r in roads:
        w = r.p.width_m
        n = min(max(1, r.p.marking_lanes), int(w // 2.4))
        for k in range(n):
            c = w / 2 - (k + 0.5) * w / n  # lane centre, > 0: left of the line's direction
            for d in (-TRACK_GAUGE_M / 2, TRACK_GAUGE_M / 2):
                ls.append(r.line)
                offs.append(c + d)
    if not ls:
        return np.array([], dtype=object)
    curves = shapely.offset_curve(np.array(ls, dtype=object), np.array(offs), quad_segs=4)
    polys = shapely.buffer(curves, TRACK_W_M / 2, cap_style="flat", quad_segs=2)
    return _clip_to_road(polys, road_area, junctions, TRACK_JUNCTION_M)


def find_junctions(roads: list[OsmRoad]) -> np.ndarray:
    """(k, 3): x, y, clear radius of every vertex shared by two or more ways."""
    import shapely

    if not roads:
        return np.zeros((0, 3))
    xy, owner, half = [], [], []
    for i, r in enumerate(roads):
        c = shapely.get_coordinates(r.line)
        xy.append(c)
        owner.append(np.full(len(c), i))
        half.append(np.full(len(c), r.p.width_m / 2))
    xy = np.concatenate(xy)
    owner = np.concatenate(owner)
    half = np.concatenate(half)
    key = np.round(xy, 3)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    n_ways = np.zeros(inv.max() + 1, int)
    pairs = np.unique(np.stack([inv, owner], 1), axis=0)
    np.add.at(n_ways, pairs[:, 0], 1)
    rad = np.zeros(inv.max() + 1)
    np.maximum.at(rad, inv, half)
    first = np.zeros(inv.max() + 1, int)
    first[inv[::-1]] = np.arange(len(inv))[::-1]
    sel = np.flatnonzero(n_ways >= 2)
    return np.column_stack([xy[first[sel]], rad[sel] + JUNCTION_CLEAR_M])
