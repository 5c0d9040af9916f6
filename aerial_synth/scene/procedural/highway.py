"""Generator ``highway``: a curving dual carriageway with at-grade junctions and local roads."""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from .builder import Builder
from .features import random_buildings
from .generators import Generator
from .roads import Road, chaikin, offset_line, wiggle


def generate_highway(b: Builder, spec: Mapping):
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
    base_long = LineString(chaikin(np.column_stack([xs, yc]), 2))
    base = base_long.intersection(b.box)
    off = median / 2 + cw / 2
    outer = median / 2 + cw  # base line to a carriageway's outer edge
    # right-hand traffic: eastbound carriageway south of the median, westbound north of it
    east = offset_line(base_long, -off).intersection(b.box)
    west = offset_line(base_long, off).intersection(b.box)
    west = LineString(list(west.coords)[::-1])
    b.roads.append(Road("eastbound", east, cw, oneway=True, lanes=lanes, shoulder_left_m=sh_l))
    b.roads.append(Road("westbound", west, cw, oneway=True, lanes=lanes, shoulder_left_m=sh_l))

    def frame_at(x):
        """Point on the base line at x and its unit tangent / left normal."""
        s = base.project(shapely.Point(x, float(np.interp(x, xs, yc))))
        p = np.asarray(base.interpolate(s).coords[0])
        q = np.asarray(base.interpolate(min(s + 1.0, base.length)).coords[0])
        r = np.asarray(base.interpolate(max(s - 1.0, 0.0)).coords[0])
        t = (q - r) / math.hypot(*(q - r))
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
        line = LineString(chaikin(line_pts, 2))
        line = line.intersection(b.box)
        if line.geom_type != "LineString":
            raise ValueError(f"crossing road at x={jx} leaves the scene")
        name = "crossing" if k == 0 else f"crossing_{k + 1}"
        cross = Road(name, line, cr_w, lanes=1)
        b.roads.append(cross)
        crossings.append(cross)
        # median opening: the crossing road plus (opening - width)/2 each side, median only
        if opening > cr_w:
            band = LineString([p - nrm * outer, p + nrm * outer]).buffer(opening / 2, cap_style="flat")
            openings.append(band.intersection(base.buffer(median / 2 + 0.05, cap_style="flat")))
    b.pads.extend(openings)
    _local_roads(b, hw, base_long, base, outer)
    b.freeze_areas()
    _dress(b, spec, crossings, base)


GENERATOR = Generator("highway", generate_highway)


def _local_roads(b: Builder, hw: Mapping, base_long, base, outer: float) -> None:
    """Two-way local roads parallel to the highway (``highway.local_roads``), clear of its
    carriageways' outer edges (``outer`` metres from the base line)."""
    from shapely.geometry import LineString

    loc = hw.get("local_roads", {}) or {}
    loc_w = float(loc.get("width_m", 7.0))
    clear = float(loc.get("clear_m", 15.0))
    for name, dist in (("local_north", loc.get("north_m")), ("local_south", loc.get("south_m"))):
        if dist is None:
            continue
        dist = float(dist)
        sign = 1.0 if name == "local_north" else -1.0
        wig = float(loc.get("wiggle_m", 0.0))
        o = offset_line(base_long, sign * dist)
        o_pts = np.asarray(o.coords)
        o_pts = np.vstack([o_pts[:-1:max(1, len(o_pts) // 16)], o_pts[-1:]])
        o_pts = wiggle(o_pts, wig, b.rng)
        line = LineString(chaikin(o_pts, 3)).intersection(b.box)
        if line.geom_type != "LineString":
            raise ValueError(f"{name} leaves the scene more than once")
        # never within ``clear`` of a carriageway's outer edge (plus the half width)
        if line.distance(base) < outer + clear + loc_w / 2:
            raise ValueError(f"{name} comes within {clear} m of the highway")
        b.roads.append(Road(name, line, loc_w, lanes=1))


def _dress(b: Builder, spec: Mapping, crossings: list, base) -> None:
    """Trees and poles beside the highway, lamp posts in its median, a few buildings."""
    import shapely

    # median stays grass (ground); trees and poles beside the highway, a few buildings
    t = spec.get("trees", {}) or {}
    if int(t.get("count", 0)) > 0:
        free = b.box.difference(b._blocked.buffer(6.0))
        b.add_tree_cluster(int(t["count"]), free, t.get("crown_radius_m", [2.5, 5.0]),
                           t.get("height_m", [7, 15]), species=t.get("species"))
    random_buildings(b, spec.get("buildings", {}) or {})
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
