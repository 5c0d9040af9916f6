"""Generator ``suburb``: a jittered street grid with sidewalks, a cul-de-sac, houses with
driveways, parking lots, street and yard trees, poles."""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from .builder import Builder
from .generators import Generator
from .parking import add_lots
from .roads import Road, offset_line


def generate_suburb(b: Builder, spec: Mapping):
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
        b.roads.append(Road(f"ns_{i}", LineString([(x, -H / 2), (x, H / 2)]), w, sidewalk_m=side))
    for j, y in enumerate(ys):
        b.roads.append(Road(f"ew_{j}", LineString([(-W / 2, y), (W / 2, y)]), sw, sidewalk_m=side))
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
        b.roads.append(Road("cul_de_sac", LineString([(xm, y0), (xm + 0.001, y0 + L)]), 6.0,
                             dead_end=True, centre="none", sidewalk_m=0.0))
    ra = b.road_area()
    # parking lots
    # lots with painted bays and an entrance from the nearest street (procedural/parking.py)
    add_lots(b, spec.get("parking_lots", []) or [], "parking_lots", ra)
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
            front = offset_line(r.line, sign * (edge + setback))
            if front.is_empty:
                continue
            s = np.arange(spacing / 2, front.length, spacing)
            for si in s:
                p = front.interpolate(si)
                q = front.interpolate(min(si + 0.5, front.length))
                d = np.array([q.x - p.x, q.y - p.y])
                if math.hypot(*d) < 1e-6:
                    continue
                d /= math.hypot(*d)
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
    _trees_and_poles(b, spec)


GENERATOR = Generator("suburb", generate_suburb)


def _trees_and_poles(b: Builder, spec: Mapping) -> None:
    """Street tree rows, yard trees and lamp posts along the wider streets."""
    t = spec.get("trees", {}) or {}
    row = t.get("street", {}) or {}
    if row:
        for r in b.roads:
            for sign in (1.0, -1.0):
                off = offset_line(r.line, sign * (r.width_m / 2 + r.sidewalk_m + float(row.get("offset_m", 1.2))))
                b.add_tree_row(off, float(row.get("spacing_m", 18.0)), row.get("crown_radius_m", [2.5, 4.0]),
                               row.get("height_m", [7, 11]), species=row.get("species"))
    yard = t.get("yard", {}) or {}
    if int(yard.get("count", 0)) > 0:
        free = b.box.difference(b._blocked.buffer(2.0))
        b.add_tree_cluster(int(yard["count"]), free, yard.get("crown_radius_m", [2.0, 4.0]),
                           yard.get("height_m", [5, 10]), species=yard.get("species"))
    p = spec.get("poles", {}) or {}
    for r in b.roads:
        if r.width_m >= float(p.get("min_road_width_m", 7.0)):
            b.add_poles_along(r, float(p.get("spacing_m", 40.0)), float(p.get("height_m", 7.0)),
                              r.sidewalk_m + float(p.get("offset_m", 0.5)))
