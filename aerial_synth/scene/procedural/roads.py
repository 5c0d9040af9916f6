"""Road model and centre-line geometry helpers of the procedural generators.

World frame: metres, x east, y north, z up.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Road", "chaikin", "wiggle", "road_polygon", "offset_line", "polygonal"]


@dataclass(frozen=True)
class Road:
    """One generated road.

    line : shapely LineString centre line, metres, world xy
    width_m : carriageway width (edge to edge)
    oneway : traffic follows the line direction (one carriageway of a dual carriageway)
    lanes : lanes in the line direction (oneway) or per direction (two-way); 0 = unmarked
    sidewalk_m : sidewalk width on both sides (0 = none)
    dead_end : end with a turning circle
    centre : centre-line style for two-way roads: "dashed", "solid" or "none"
    """

    name: str
    line: Any
    width_m: float
    oneway: bool = False
    lanes: int = 1
    sidewalk_m: float = 0.0
    dead_end: bool = False
    centre: str = "dashed"
    shoulder_left_m: float = 0.0


def chaikin(pts: np.ndarray, iterations: int = 3) -> np.ndarray:
    """Corner-cutting smoothing of an open polyline (end points kept). pts: (n, 2)."""
    for _ in range(iterations):
        if len(pts) < 3:
            return pts
        a, b = pts[:-1], pts[1:]
        q = 0.75 * a + 0.25 * b
        r = 0.25 * a + 0.75 * b
        mid = np.empty((2 * (len(pts) - 1), 2))
        mid[0::2] = q
        mid[1::2] = r
        pts = np.vstack([pts[:1], mid[1:-1], pts[-1:]])
    return pts


def wiggle(pts: np.ndarray, amp_m: float, rng: np.random.Generator) -> np.ndarray:
    """Move interior points sideways by up to amp_m (seeded), keep the ends."""
    pts = np.array(pts, float)
    if amp_m <= 0 or len(pts) < 3:
        return pts
    d = np.gradient(pts, axis=0)
    n = np.column_stack([-d[:, 1], d[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    off = rng.uniform(-amp_m, amp_m, len(pts))
    off[0] = off[-1] = 0.0
    return pts + n * off[:, None]


def road_polygon(r: Road):
    import shapely

    poly = r.line.buffer(r.width_m / 2, cap_style="flat", join_style="round", quad_segs=8)
    if r.dead_end:
        end = shapely.Point(r.line.coords[-1])
        poly = poly.union(end.buffer(max(r.width_m, 7.0), quad_segs=12))
    return poly



def offset_line(line, d: float):
    """Offset a centre line by d metres (positive = left of the line direction)."""
    out = line.offset_curve(d, quad_segs=8, join_style="round")
    return out



def polygonal(g):
    """The polygon parts of a shapely geometry (drops stray lines/points of a clip).

    ``g`` is the result of one overlay (intersection, difference), so its polygons neither
    overlap nor share an edge: they are gathered into a MultiPolygon, not unioned again
    (a union of the parts cost seconds on a 2 km city's markings)."""
    import shapely

    polys = []
    for p in shapely.get_parts(g):
        if p.geom_type == "Polygon":
            polys.append(p)
        elif p.geom_type in ("MultiPolygon", "GeometryCollection"):
            polys.extend(q for q in shapely.get_parts(polygonal(p)))
    polys = [p for p in polys if not p.is_empty]
    if not polys:
        return shapely.Polygon()
    return polys[0] if len(polys) == 1 else shapely.MultiPolygon(polys)

