"""Parking lots and depots in generated scenes: painted bay lines, entrances, the ``depot``.

A lot is a rectangle (any rotation) divided into bays by
:func:`aerial_synth.scene.parking_layout.layout_bays` (the pattern is described there), the
same function placement fills bays with, so painted lines and parked cars agree.

Frames: world metres, x east, y north; angles in radians unless named ``_deg``; a bay's
``axis_rad`` points from its aisle into the bay (the heading of a car parked nose-in).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ... import validators as V
from ...errors import ConfigError, SceneError
from ..parking_layout import bay_markings, layout_bays, lot_frame, parse_layout
from .generators import Generator
from .roads import Road

__all__ = [
    "lot_entrance",
    "add_lots",
    "generate_depot",
    "DEPOT_BUS_LAYOUT",
    "DEPOT_TRUCK_LAYOUT",
]


def lot_entrance(lot, road_area, width_m: float = 6.0, reach_m: float = 60.0):
    """A strip joining a lot to the nearest road: from the middle of the short end nearest a
    road (else the long side nearest one) straight out to the road. ``None`` when no road is
    within ``reach_m``."""
    import shapely
    from shapely.geometry import LineString

    fr = lot_frame(lot)
    best = None
    for long_side in (False, True):
        for sgn in (1.0, -1.0):
            if long_side:
                mid_uv, out = np.array([0.0, sgn * fr.short_m / 2]), np.array([0.0, sgn])
            else:
                mid_uv, out = np.array([sgn * fr.long_m / 2, 0.0]), np.array([sgn, 0.0])
            p = fr.to_world(mid_uv)
            d = fr.to_world(mid_uv + out) - p
            ray = LineString([p - d * 1.0, p + d * reach_m])
            hit = ray.intersection(road_area)
            if hit.is_empty:
                continue
            dist = shapely.distance(shapely.Point(p), hit)
            if best is None or dist < best[0]:
                best = (dist, p, d)
        if best is not None:
            break
    if best is None:
        return None
    dist, p, d = best
    strip = LineString([p - d * 2.0, p + d * (dist + 1.0)])
    return strip.buffer(width_m / 2, cap_style="flat")


def _lot_polygon(entry: Mapping, where: str):
    import shapely
    from shapely import affinity

    c = V.sequence_of_numbers(f"{where}.center", entry.get("center"))
    s = V.sequence_of_numbers(f"{where}.size_m", entry.get("size_m"), positive_only=True)
    if len(c) != 2 or len(s) != 2:
        raise SceneError(f"{where}: center and size_m must be [x, y] and [width, height] in metres, "
                         f"got {V.show(entry.get('center'))} and {V.show(entry.get('size_m'))}")
    rot = V.in_range(f"{where}.rotation_deg", entry.get("rotation_deg", 0.0), -360.0, 360.0)
    box = shapely.box(c[0] - s[0] / 2, c[1] - s[1] / 2, c[0] + s[0] / 2, c[1] + s[1] / 2)
    return affinity.rotate(box, rot, origin=(c[0], c[1])) if rot else box


_LOT_KEYS = ("center", "size_m", "rotation_deg", "layout", "entrance")


def add_lots(b, lots, where: str = "parking_lots", road_area=None) -> list:
    """Add lots (spec entries ``{center, size_m, rotation_deg, layout, entrance}``) to a
    builder: the lot surface, an entrance to the nearest road (unless ``entrance: false``),
    the painted bays, and a hint per lot in ``b.parking_hints`` (id, rectangle, layout).
    Returns the lot polygons (entrances included). Raises SceneError for a bad entry or a
    bay (with its aisle and end lanes) larger than its lot."""
    out = []
    hints = b.__dict__.setdefault("parking_hints", [])
    marks = b.__dict__.setdefault("lot_markings", [])
    for k, entry in enumerate(lots or []):
        w = f"{where}[{k}]"
        try:
            V.mapping(w, entry)
            V.known_keys(w, entry, _LOT_KEYS)
            poly = _lot_polygon(entry, w)
        except ConfigError as exc:
            raise SceneError(str(exc)) from None
        lay = parse_layout(entry.get("layout"), f"{w}.layout")
        fr = lot_frame(poly)
        need_long, need_short = lay.min_lot_m()
        if need_long > fr.long_m + 1e-9 or need_short > fr.short_m + 1e-9:
            raise SceneError(
                f"{w}.layout: a bay of {lay.bay_width_m:g} x {lay.bay_length_m:g} m at {lay.angle_deg:g} deg "
                f"with a {lay.aisle_m:g} m aisle needs a lot of at least {need_long:.1f} x {need_short:.1f} m, "
                f"got {fr.long_m:g} x {fr.short_m:g} m"
            )
        bays = layout_bays(fr, lay)
        marks.append(bay_markings(bays, lay))
        b.parking.append(poly)
        shape = poly
        if entry.get("entrance", True) and road_area is not None:
            ent = lot_entrance(poly, road_area)
            if ent is not None:
                b.parking.append(ent)
                shape = poly.union(ent)
        hints.append({"id": len(hints), "center_xy": [fr.cx, fr.cy], "row_deg": float(np.degrees(fr.u_rad)),
                      "long_m": fr.long_m, "short_m": fr.short_m, "layout": lay.to_dict(),
                      "bays": len(bays)})
        out.append(shape)
    return out


#: Depot layouts: long perpendicular bays for 12-13 m buses and for 16.5 m semi-trailers.
DEPOT_BUS_LAYOUT = {"bay_width_m": 3.5, "bay_length_m": 14.0, "angle_deg": 90, "aisle_m": 16.0}
DEPOT_TRUCK_LAYOUT = {"bay_width_m": 3.8, "bay_length_m": 18.0, "angle_deg": 90, "aisle_m": 20.0}


def generate_depot(b, spec: Mapping):
    """Generator ``depot``: an access road along the south edge with one north-south street,
    a bus yard and a truck yard (long bays, entrances to the street network), a garage
    building, trees and poles. Spec keys: ``road_width_m``, ``yards`` (a list of lots as in
    ``parking_lots``; default one bus yard and one truck yard), ``garage`` ``{center, size_m,
    height_m}``, ``trees: {count}``."""
    import shapely
    from shapely.geometry import LineString


    W, H = (float(v) for v in spec["size_m"])
    rw = float(spec.get("road_width_m", 8.0))
    y_road = -H / 2 + 18.0
    b.roads.append(Road("access", LineString([(-W / 2, y_road), (W / 2, y_road)]), rw, sidewalk_m=2.0))
    b.roads.append(Road("depot_street", LineString([(0.0, y_road), (0.0, H / 2)]), rw, sidewalk_m=2.0))
    ra = b.road_area()
    yards = spec.get("yards")
    if yards is None:
        yards = [
            {"center": [-W / 4, y_road + 48.0], "size_m": [W / 2 - 20.0, 70.0], "layout": DEPOT_BUS_LAYOUT},
            {"center": [W / 4, y_road + 60.0], "size_m": [W / 2 - 20.0, 94.0], "layout": DEPOT_TRUCK_LAYOUT},
        ]
    lots = add_lots(b, yards, "yards", ra)
    g = spec.get("garage") or {"center": [-W / 4, H / 2 - 18.0], "size_m": [W / 2 - 30.0, 22.0], "height_m": 9.0}
    gc = V.sequence_of_numbers("garage.center", g["center"])
    gs = V.sequence_of_numbers("garage.size_m", g["size_m"], positive_only=True)
    block = shapely.union_all([ra] + lots)
    b._blocked = block
    b.try_building(shapely.box(gc[0] - gs[0] / 2, gc[1] - gs[1] / 2, gc[0] + gs[0] / 2, gc[1] + gs[1] / 2),
                   float(g.get("height_m", 9.0)), clearance=1.0)
    b.freeze_areas()
    t = spec.get("trees", {}) or {}
    n = int(t.get("count", 40))
    if n > 0:
        free = b.box.difference(b._blocked.buffer(3.0))
        b.add_tree_cluster(n, free, [2.0, 3.5], [5, 9], species=t.get("species"))
    for r in b.roads:
        b.add_poles_along(r, 40.0, 8.0, r.sidewalk_m + 0.5)


GENERATOR = Generator("depot", generate_depot)
