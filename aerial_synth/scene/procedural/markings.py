"""Lane markings of procedural roads: dashed and solid lines, clipped out of junctions."""

from __future__ import annotations

from typing import Mapping

from .roads import Road, offset_line

__all__ = ["road_markings", "dashes", "solid"]


def dashes(line, dash_m: float, gap_m: float, width_m: float):
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


def solid(line, width_m: float):
    return line.buffer(width_m / 2, cap_style="flat")



def road_markings(r: Road, others_area, cfg: Mapping):
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
        parts.append(solid(offset_line(r.line, w / 2 - edge_in), mw))  # left edge
        parts.append(solid(offset_line(r.line, -(w / 2 - edge_in)), mw))  # right edge
        for k in range(1, r.lanes):
            parts.append(dashes(offset_line(r.line, left - k * lane_w), dash, gap, mw))
    else:
        if w >= float(cfg.get("centre_line_min_width_m", 6.0)):
            if r.centre == "solid":
                parts.append(solid(r.line, mw))
            elif r.centre == "dashed":
                parts.append(dashes(r.line, dash, gap, mw))
        if w >= float(cfg.get("edge_line_min_width_m", 7.0)):
            parts.append(solid(offset_line(r.line, w / 2 - edge_in), mw))
            parts.append(solid(offset_line(r.line, -(w / 2 - edge_in)), mw))
    m = shapely.union_all([p for p in parts if not p.is_empty])
    own = r.line.buffer(w / 2 - 0.05, cap_style="flat")
    m = m.intersection(own)
    if others_area is not None and not others_area.is_empty:
        m = m.difference(others_area.buffer(float(cfg.get("junction_clear_m", 1.5))))
    return m

